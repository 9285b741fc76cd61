"""Validation of what the browser sends: pseudonymous ids, choices, bounded numbers.

Every function takes the raw JSON value (or form string) and the field name, and either returns a
clean Python value or raises :class:`bowden.errors.RequestError` naming the field and what is
accepted. Handlers validate a whole request before they change anything, so a refused request
leaves the server and the study store exactly as they were.
"""

from __future__ import annotations

import math
import re
from collections.abc import Collection

from bowden.contracts import is_participant_id
from bowden.errors import RequestError


def participant_id(value: object, field: str = "participant") -> str:
    """A pseudonymous participant id such as ``P01``, exactly as sent.

    The rule is :func:`bowden.contracts.is_participant_id`, the one the study store and the recorder
    apply: the whole text, 1–4 capital letters then 1–4 digits. Digits are required and lower-case
    letters refused, so a name ("Anna", "anna smith") can never be stored by mistake; surrounding
    spaces or a line break are refused too, not trimmed (the pages trim what is typed), so an id is
    never stored other than it was sent.
    """
    if not isinstance(value, str):
        raise RequestError(f"{field}: expected a pseudonymous id such as P01, got {type(value).__name__}")
    if not is_participant_id(value):
        raise RequestError(
            f"{field}: {value[:20]!r} is not a pseudonymous id; use 1–4 capital letters and 1–4 digits "
            "such as P01, nothing around them (never a name)"
        )
    return value


def choice(value: object, options: Collection[str], field: str) -> str:
    """One of ``options`` (exact match)."""
    if not isinstance(value, str) or value not in options:
        shown = value[:30] if isinstance(value, str) else type(value).__name__
        raise RequestError(f"{field}: {shown!r} is not one of {', '.join(options)}")
    return value


def integer_in(value: object, low: int, high: int, field: str) -> int:
    """An integer in ``[low, high]``; digit strings (from HTML forms) are accepted."""
    if isinstance(value, bool):
        raise RequestError(f"{field}: expected an integer from {low} to {high}, got a boolean")
    if isinstance(value, str) and re.fullmatch(r"\s*-?[0-9]{1,6}\s*", value):
        value = int(value)
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, int) or not low <= value <= high:
        shown = value if isinstance(value, int | float) else type(value).__name__
        raise RequestError(f"{field}: expected an integer from {low} to {high}, got {shown!r}")
    return value


def whole_number_in(value: object, low: int, high: int, field: str) -> int:
    """A JSON whole number in ``[low, high]``; text ("3") is refused, as the study store refuses it."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        shown = repr(value[:10]) if isinstance(value, str) else type(value).__name__
        raise RequestError(f"{field}: expected a whole number from {low} to {high}, got {shown}")
    return integer_in(value, low, high, field)


def number_in(value: object, low: float, high: float, field: str) -> float:
    """A finite number in ``[low, high]``; numeric strings (from HTML forms) are accepted."""
    if isinstance(value, bool):
        raise RequestError(f"{field}: expected a number from {low:g} to {high:g}, got a boolean")
    if isinstance(value, str):
        text = value
        try:
            value = float(text) if len(text) <= 32 else math.nan
        except ValueError:
            raise RequestError(f"{field}: {text[:20]!r} is not a number") from None
    if not isinstance(value, int | float) or not math.isfinite(value) or not low <= value <= high:
        shown = value if isinstance(value, int | float) else type(value).__name__
        raise RequestError(f"{field}: expected a number from {low:g} to {high:g}, got {shown!r}")
    return float(value)


def no_unknown_fields(payload: dict[str, object], known: Collection[str], where: str) -> None:
    """Refuse fields the server does not know (typos must not be silently ignored)."""
    unknown = sorted(set(payload) - set(known))
    if unknown:
        names = ", ".join(repr(name[:30]) for name in unknown[:5])
        raise RequestError(f"{where}: unknown field(s) {names}; known: {', '.join(sorted(known))}")
