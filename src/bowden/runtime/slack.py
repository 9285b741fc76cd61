"""Taking up the cable's slack before the first stroke or the first cycle of a trial.

A Bowden cable hangs slack while the motor is limp. Commanding a tension straight away lets the
spool spin freely until the cable snaps taut — a jerk on the arm, and on a person. So a session
starts the way exosuit labs start one: the motor reels in slowly in velocity mode (MIT mode with
``kp`` = 0: τ = kd·(v − ω), so the torque can never exceed ``kd·v``) until the cable's tension
reaches a small pretension, measured by the load cell or, without one, estimated from the motor's
torque over the pulley radius; then the caller switches to its own mode. No tension within
``timeout_s`` is a fault: the cable is probably not attached.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from bowden.errors import ParameterError

_REACH_MARGIN = 1.5  # kd·v/radius over the pretension (measured: friction ate 30 % on the simulated suit)


@dataclass(frozen=True, kw_only=True)
class SlackTakeUp:
    """How the slack is taken up.

    Parameters
    ----------
    velocity_rad_s
        Spool velocity while reeling in (> 0 reels in).
    kd_nms_rad
        Velocity gain: the torque is at most ``kd·velocity`` (a stalled spool), so the pretension must
        be reachable: ``kd·velocity / pulley radius`` above it.
    pretension_n
        Tension at which the cable counts as taut.
    timeout_s
        Longest take-up before it is a fault.
    pulley_radius_m
        Turns the motor's torque into the cable's pull when no load cell is connected (N = Nm / m).
    """

    velocity_rad_s: float = 0.5
    kd_nms_rad: float = 1.0
    pretension_n: float = 5.0
    timeout_s: float = 10.0
    pulley_radius_m: float = 0.035

    def __post_init__(self) -> None:
        for name in ("velocity_rad_s", "kd_nms_rad", "pretension_n", "timeout_s", "pulley_radius_m"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0.0):
                raise ParameterError(f"SlackTakeUp.{name} must be positive and finite, got {value!r}")
        if self.velocity_rad_s > 3.0:
            raise ParameterError(f"SlackTakeUp.velocity_rad_s must be at most 3 rad/s (a slow reel-in), "
                                 f"got {self.velocity_rad_s}")
        # The motor's and the sheath's friction take their share of kd·v: ask for half again as much.
        if self.max_pull_n(self.pulley_radius_m) < _REACH_MARGIN * self.pretension_n:
            raise ParameterError(f"SlackTakeUp: the pretension ({self.pretension_n:g} N) cannot be reached: "
                                 f"kd·v/radius = {self.max_pull_n(self.pulley_radius_m):.1f} N, less than "
                                 f"{_REACH_MARGIN:g}× the pretension (raise kd or the velocity)")

    def max_pull_n(self, spool_radius_m: float | None = None) -> float:
        """The largest tension the take-up can reach on a pulley of ``spool_radius_m`` (N; default
        :attr:`pulley_radius_m`)."""
        radius = self.pulley_radius_m if spool_radius_m is None else spool_radius_m
        return self.kd_nms_rad * self.velocity_rad_s / radius

    def pull_n(self, tension_n: float, motor_torque_nm: float) -> float:
        """The cable's pull now: the load cell's reading if there is one, else the motor's torque
        over the pulley radius."""
        if math.isfinite(tension_n):
            return tension_n
        return motor_torque_nm / self.pulley_radius_m if math.isfinite(motor_torque_nm) else math.nan


def take_up_slack(
    config: SlackTakeUp,
    cycle: Callable[[float, float], float],
    *,
    period_s: float,
    fail: Callable[[str], Exception],
) -> int:
    """Reel in until the tension reaches ``config.pretension_n``; returns the cycles it took.

    Parameters
    ----------
    cycle
        One control cycle of the caller at its rate: ``cycle(velocity_rad_s, kd)`` commands the motor
        in velocity mode, runs the caller's watchdogs, waits for the next deadline and returns the
        tension measured now (N; the load cell, or the motor's torque over the pulley radius).
    period_s
        The caller's cycle period (s), to count the timeout in cycles (immune to a stalled host).
    fail
        Builds the exception raised on a timeout (the caller's fault type).
    """
    cycles = max(1, math.ceil(config.timeout_s / period_s))
    tension = math.nan
    for n in range(1, cycles + 1):
        tension = cycle(config.velocity_rad_s, config.kd_nms_rad)
        if tension >= config.pretension_n:
            return n
    raise fail(f"the cable did not tighten: {tension:.1f} N after {config.timeout_s:g} s of take-up "
               f"(pretension {config.pretension_n:g} N); is it attached to the arm?")
