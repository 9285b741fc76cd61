"""A participant's session as a plan: the conditions in their order, each at every speed.

The paper's protocol ("Protocol"): no suit first (the EMG baseline), then the support conditions in a
randomised order, each at V1, V2, V3, ten repetitions a trial, a break with the questionnaires after
each condition. Every number is a field of :class:`StudyProtocol`; the plan is worked out once, from
a recorded seed (random order) or the participant's place in the study (Latin square), and stored
before the first trial, so that a restarted server resumes the same plan.

Pure functions and frozen dataclasses: no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Final, Literal

import numpy as np

from bowden.contracts import (
    CONDITION_NO_SUIT,
    CONDITION_PRETENSION,
    CONDITION_SUPPORT_25,
    CONDITION_SUPPORT_50,
    REPETITIONS_PER_TRIAL,
    SPEEDS,
)
from bowden.errors import ParameterError
from bowden.protocol.catalogue import PAPER, Catalogue

Order = Literal["random", "latin_square"]
ORDERS: Final = ("random", "latin_square")
PAPER_BREAK_S: Final = 300.0  # the 5-minute break with the questionnaires after each condition
MAX_BREAK_S: Final = 3600.0  # a longer break is a new session


@dataclass(frozen=True, kw_only=True)
class StudyProtocol:
    """The numbers of a session.

    Parameters
    ----------
    baseline
        The condition run first, in no random place (paper: no suit, the EMG baseline); None: none.
    conditions
        The conditions ordered for each participant (paper: pretension, 25 %, 50 %).
    speeds
        The speeds of every condition, in this order (paper: V1, V2, V3).
    repetitions
        Raise-and-lower cycles per trial (paper: 10).
    lead_in_s
        Rest before the reference starts moving, s.
    break_s
        The break after each condition, s (paper: 5 min).
    order
        ``"random"`` (a permutation drawn from the session's seed) or ``"latin_square"``
        (counterbalanced over participants: a Williams design, one row per participant in turn).
    catalogue
        The lab's own conditions and speeds (:mod:`bowden.protocol.catalogue`) that ``conditions``
        and ``speeds`` may name besides the paper's; stored with the plan.
    """

    baseline: str | None = CONDITION_NO_SUIT
    conditions: tuple[str, ...] = (CONDITION_PRETENSION, CONDITION_SUPPORT_25, CONDITION_SUPPORT_50)
    speeds: tuple[str, ...] = SPEEDS
    repetitions: int = REPETITIONS_PER_TRIAL
    lead_in_s: float = 2.0
    break_s: float = PAPER_BREAK_S
    order: Order = "random"
    catalogue: Catalogue = PAPER

    def __post_init__(self) -> None:
        named = [*([self.baseline] if self.baseline is not None else []), *self.conditions]
        known = self.catalogue.condition_names
        unknown = [c for c in named if c not in known]
        if unknown:
            raise ParameterError(
                f"StudyProtocol.conditions: unknown condition(s) {', '.join(map(str, unknown))} "
                f"(known: {', '.join(known)}; define your own with --define-condition NAME=SUPPORT)"
            )
        if len(set(named)) != len(named) or not self.conditions:
            raise ParameterError(
                f"StudyProtocol.conditions must be distinct and not empty, got {', '.join(named) or 'none'}"
            )
        speeds = self.catalogue.speed_names
        bad = [s for s in self.speeds if s not in speeds]
        if bad or not self.speeds or len(set(self.speeds)) != len(self.speeds):
            raise ParameterError(
                f"StudyProtocol.speeds must be distinct speeds of {', '.join(speeds)} (define your own "
                f"with --define-speed NAME=DEG_S), got {', '.join(map(str, self.speeds)) or 'none'}"
            )
        repetitions = self.repetitions
        if isinstance(repetitions, bool) or not isinstance(repetitions, int) or not 1 <= repetitions <= 30:
            raise ParameterError(f"StudyProtocol.repetitions must be 1-30, got {self.repetitions!r}")
        if not (math.isfinite(self.lead_in_s) and 0.0 <= self.lead_in_s <= 10.0):
            raise ParameterError(f"StudyProtocol.lead_in_s must be 0-10 s, got {self.lead_in_s!r}")
        if not (math.isfinite(self.break_s) and 0.0 <= self.break_s <= MAX_BREAK_S):
            raise ParameterError(f"StudyProtocol.break_s must be 0-{MAX_BREAK_S:g} s, got {self.break_s!r}")
        if self.order not in ORDERS:
            raise ParameterError(f"StudyProtocol.order must be one of {ORDERS}, got {self.order!r}")

    def to_json(self) -> dict[str, Any]:
        return {
            "baseline": self.baseline,
            "conditions": list(self.conditions),
            "speeds": list(self.speeds),
            "repetitions": self.repetitions,
            "lead_in_s": self.lead_in_s,
            "break_s": self.break_s,
            "order": self.order,
            "catalogue": self.catalogue.to_json(),
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> StudyProtocol:
        return cls(
            baseline=data["baseline"],
            conditions=tuple(data["conditions"]),
            speeds=tuple(data["speeds"]),
            repetitions=int(data["repetitions"]),
            lead_in_s=float(data["lead_in_s"]),
            break_s=float(data["break_s"]),
            order=data["order"],
            catalogue=Catalogue.from_json(data.get("catalogue")),  # absent: a plan before custom protocols
        )


@dataclass(frozen=True, kw_only=True)
class PlanStep:
    """One trial of the plan (``position`` counts from 1)."""

    position: int
    condition: str
    speed: str
    repetitions: int


def williams_square(n: int) -> list[list[int]]:
    """Rows of a Williams design for ``n`` treatments (each follows each other equally often).

    Williams (1949, Aust J Sci Res A 2:149): the first row 0, 1, n−1, 2, n−2, …, the others shifted
    by one modulo n; for odd n the reversed rows are added (2n rows) to balance first-order carry-over.
    """
    if n < 1:
        raise ParameterError(f"a Latin square needs at least one treatment, got {n}")
    first, low, high = [0], 1, n - 1
    while len(first) < n:
        first.append(low)
        low += 1
        if len(first) < n:
            first.append(high)
            high -= 1
    rows = [[(value + shift) % n for value in first] for shift in range(n)]
    if n % 2 == 1 and n > 1:
        rows += [list(reversed(row)) for row in rows]
    return rows


def condition_order(protocol: StudyProtocol, *, seed: int, sequence: int) -> tuple[str, ...]:
    """The order of the session's conditions: the baseline first, then the others.

    ``seed`` draws the permutation of a random order (numpy's PCG64); ``sequence`` (the participant's
    place among the study's counterbalanced sessions, from 0) picks the Latin square's row.
    """
    rest = protocol.conditions
    if protocol.order == "random":
        permutation = np.random.default_rng(seed).permutation(len(rest))
        ordered = tuple(rest[int(i)] for i in permutation)
    else:
        rows = williams_square(len(rest))
        ordered = tuple(rest[i] for i in rows[sequence % len(rows)])
    return ((protocol.baseline,) if protocol.baseline is not None else ()) + ordered


def make_plan(protocol: StudyProtocol, order: tuple[str, ...]) -> tuple[PlanStep, ...]:
    """Every trial of the session: each condition of ``order`` at each speed, in the protocol's order."""
    steps: list[PlanStep] = []
    for condition in order:
        for speed in protocol.speeds:
            steps.append(
                PlanStep(position=len(steps) + 1, condition=condition, speed=speed,
                         repetitions=protocol.repetitions)
            )
    return tuple(steps)
