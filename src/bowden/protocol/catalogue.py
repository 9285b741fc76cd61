"""The named conditions and speeds a protocol may use: the paper's, and a lab's own.

The paper's four conditions and three speeds (``bowden.contracts``) are always known and keep their
meaning and labels. A lab adds its own as named definitions — a condition is a gravity-support
fraction (``support_70=0.7``), a speed a peak elevation speed of the minimum-jerk reference in °/s
(``V4=240``) — given to ``bowden serve`` and ``bowden run`` by the same flags (``--define-condition``,
``--define-speed``) and stored with each session plan. One rule holds everywhere: a trial runs its
condition's support at its speed's peak, and both are recorded in the trial (``support`` column,
``speed_peak_deg_s`` in its metadata), so a name keeps one meaning in a study store.

Pure functions and frozen dataclasses: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Final, Literal

from bowden.contracts import (
    CONDITION_LABELS,
    CONDITION_SUPPORT,
    CONDITIONS,
    PROTOCOL_NAME_RULE,
    SPEED_PEAK_DEG_S,
    SPEEDS,
    is_protocol_name,
)
from bowden.errors import ParameterError

MIN_PEAK_DEG_S: Final = 10.0
MAX_PEAK_DEG_S: Final = 400.0

Support = float | Literal["pretension"] | None  # None: no suit (zero torque)


def check_name(name: object, kind: str) -> str:
    """``name`` if it follows the one rule of ``contracts.is_protocol_name``.

    Raises
    ------
    ParameterError
        One line naming the rule.
    """
    if not is_protocol_name(name):
        raise ParameterError(f"{kind} name {name!r} is not allowed: use {PROTOCOL_NAME_RULE}")
    return str(name)


@dataclass(frozen=True, kw_only=True)
class Catalogue:
    """The conditions and speeds known to a protocol: the paper's plus ``conditions`` and ``speeds``.

    Parameters
    ----------
    conditions
        A lab's own conditions, ``(name, support fraction)`` pairs; the fraction is in (0, 1].
    speeds
        A lab's own speeds, ``(name, peak elevation speed in °/s)`` pairs, 10–400 °/s.
    """

    conditions: tuple[tuple[str, float], ...] = ()
    speeds: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        for name, support in self.conditions:
            check_name(name, "condition")
            if name in CONDITIONS:
                raise ParameterError(
                    f"condition {name} is the paper's (support {CONDITION_SUPPORT[name]}): "
                    "give yours another name"
                )
            if isinstance(support, bool) or not isinstance(support, int | float) \
                    or not (math.isfinite(support) and 0.0 < support <= 1.0):
                raise ParameterError(
                    f"condition {name}: support must be a fraction in (0, 1], got {support!r}"
                )
        for name, peak in self.speeds:
            check_name(name, "speed")
            if name in SPEEDS:
                raise ParameterError(
                    f"speed {name} is the paper's ({SPEED_PEAK_DEG_S[name]:g} °/s): give yours another name"
                )
            if isinstance(peak, bool) or not isinstance(peak, int | float) \
                    or not (math.isfinite(peak) and MIN_PEAK_DEG_S <= peak <= MAX_PEAK_DEG_S):
                raise ParameterError(
                    f"speed {name}: the peak must be {MIN_PEAK_DEG_S:g}–{MAX_PEAK_DEG_S:g} °/s, got {peak!r}"
                )
        for kind, pairs in (("condition", self.conditions), ("speed", self.speeds)):
            names = [name for name, _ in pairs]
            if len(set(names)) != len(names):
                raise ParameterError(f"each {kind} is defined once, got {', '.join(names)}")

    # --- what is known ---------------------------------------------------------------------------
    @property
    def condition_names(self) -> tuple[str, ...]:
        """The paper's conditions, then the lab's own in the order defined."""
        return (*CONDITIONS, *(name for name, _ in self.conditions))

    @property
    def speed_names(self) -> tuple[str, ...]:
        return (*SPEEDS, *(name for name, _ in self.speeds))

    def is_custom(self, name: str) -> bool:
        """Whether ``name`` is one of the lab's own conditions or speeds."""
        return name in dict(self.conditions) or name in dict(self.speeds)

    def support(self, condition: str) -> Support:
        """The support ``condition`` stands for: a fraction, ``"pretension"`` or None (no suit)."""
        if condition in CONDITION_SUPPORT:
            value = CONDITION_SUPPORT[condition]
            return None if value is None else "pretension" if isinstance(value, str) else float(value)
        own = dict(self.conditions)
        if condition not in own:
            raise ParameterError(
                f"unknown condition {condition!r} (known: {', '.join(self.condition_names)})"
            )
        return float(own[condition])

    def peak_deg_s(self, speed: str) -> float:
        """The peak elevation speed of ``speed``'s reference, °/s."""
        if speed in SPEED_PEAK_DEG_S:
            return SPEED_PEAK_DEG_S[speed]
        own = dict(self.speeds)
        if speed not in own:
            raise ParameterError(f"unknown speed {speed!r} (known: {', '.join(self.speed_names)})")
        return float(own[speed])

    def label(self, condition: str) -> str:
        """The paper's short label (``25%``), or a lab's condition's own name."""
        return CONDITION_LABELS.get(condition, condition)

    def conditions_with_support(self, support: Support) -> list[str]:
        """The known conditions that stand for ``support``."""
        return [c for c in self.condition_names if self.support(c) == support]

    # --- combining -------------------------------------------------------------------------------
    def merged(self, other: Catalogue) -> Catalogue:
        """Both catalogues' definitions; a name defined by both must mean the same.

        Raises
        ------
        ParameterError
            If a name has two meanings (one line naming both).
        """
        conditions, speeds = dict(self.conditions), dict(self.speeds)
        for kind, mine, theirs, unit in (
            ("condition", conditions, dict(other.conditions), "support "),
            ("speed", speeds, dict(other.speeds), "°/s peak "),
        ):
            for name, value in theirs.items():
                if name in mine and not math.isclose(mine[name], value, rel_tol=1e-9, abs_tol=1e-12):
                    raise ParameterError(
                        f"{kind} {name} is defined as {unit}{mine[name]:g} and as {unit}{value:g}: "
                        "a name keeps one meaning in a study (name the new one otherwise)"
                    )
                mine.setdefault(name, value)
        return Catalogue(conditions=tuple(conditions.items()), speeds=tuple(speeds.items()))

    # --- storing ---------------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        return {"conditions": dict(self.conditions), "speeds": dict(self.speeds)}

    @classmethod
    def from_json(cls, data: Any) -> Catalogue:
        """From :meth:`to_json` (None: the paper's only, as in stores written before custom protocols)."""
        if data is None:
            return PAPER
        if not isinstance(data, dict):
            raise ParameterError(f"a catalogue is an object of conditions and speeds, got {data!r}")
        conditions, speeds = data.get("conditions", {}), data.get("speeds", {})
        if not isinstance(conditions, dict) or not isinstance(speeds, dict):
            raise ParameterError("a catalogue's conditions and speeds are objects of name: value")
        return cls(conditions=tuple(conditions.items()), speeds=tuple(speeds.items()))


PAPER: Final = Catalogue()


def _definition(text: str, kind: str, flag: str) -> tuple[str, str]:
    name, sep, value = text.partition("=")
    if not sep or not value.strip():
        example = "support_70=0.7" if kind == "condition" else "V4=240"
        raise ParameterError(f"{flag}: expected NAME=VALUE such as {example}, got {text!r}")
    try:
        return check_name(name, kind), value.strip()
    except ParameterError as error:
        raise ParameterError(f"{flag}: {error}") from None


def parse_condition_definition(text: str, flag: str = "--define-condition") -> tuple[str, float]:
    """``support_70=0.7`` or ``support_70=70%``: a condition and its support fraction."""
    name, value = _definition(text, "condition", flag)
    try:
        support = float(value[:-1]) / 100.0 if value.endswith("%") else float(value)
    except ValueError:
        raise ParameterError(f"{flag}: {name}'s support must be a fraction (0.7) or percent (70%), "
                             f"got {value!r}") from None
    return name, support


def parse_speed_definition(text: str, flag: str = "--define-speed") -> tuple[str, float]:
    """``V4=240``: a speed and its reference's peak elevation speed, °/s."""
    name, value = _definition(text, "speed", flag)
    try:
        return name, float(value)
    except ValueError:
        raise ParameterError(f"{flag}: {name}'s peak must be a number of °/s, got {value!r}") from None


def catalogue_of(conditions: list[str] | None, speeds: list[str] | None) -> Catalogue:
    """The catalogue of the ``--define-condition`` and ``--define-speed`` flags (errors name the flag)."""
    defined = tuple(parse_condition_definition(t) for t in conditions or ())
    try:
        Catalogue(conditions=defined)
    except ParameterError as error:
        raise ParameterError(f"--define-condition: {error}") from None
    try:
        return Catalogue(conditions=defined, speeds=tuple(parse_speed_definition(t) for t in speeds or ()))
    except ParameterError as error:
        text = str(error)
        raise ParameterError(text if text.startswith("--") else f"--define-speed: {text}") from None
