"""The one check of a number parameter: finite, not a bool, within its range.

Frozen parameter dataclasses call it from ``__post_init__`` so a bad value is refused where it is
made, with a message that names the field.
"""

from __future__ import annotations

import math

from bowden.errors import ParameterError


def check_number(
    value: object, name: str, low: float = -math.inf, high: float = math.inf, *, low_open: bool = False
) -> float:
    """``value`` as a float, or :class:`ParameterError` naming ``name`` and the range.

    The range is ``[low, high]``, or ``(low, high]`` with ``low_open``; NaN and ±inf are refused
    whatever the range, and so is a bool (``True`` is an int to Python, never a measurement).
    """
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ParameterError(f"{name} must be a finite number, got {value!r}")
    inside = (value > low if low_open else value >= low) and value <= high
    if not inside:
        bracket = "(" if low_open else "["
        raise ParameterError(f"{name} = {value!r} is outside its valid range {bracket}{low:g}, {high:g}]")
    return float(value)


def check_field(owner: object, name: str, low: float = -math.inf, high: float = math.inf,
                *, low_open: bool = False) -> float:
    """:func:`check_number` of the attribute ``name`` of a parameter object, named ``Type.name``."""
    return check_number(getattr(owner, name), f"{type(owner).__name__}.{name}", low, high, low_open=low_open)
