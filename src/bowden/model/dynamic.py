"""Dynamic compensation: the transmission's friction through reversals and with speed, plus the motor.

The paper's inverse model blends two static lines by the sign of a lagging elevation velocity, and its
own discussion attributes the tension spike at the onset of lowering to stiction when the arm and
cable change direction. This model keeps the load-proportional friction of the two lines and adds
what the lines leave out (motor torque τ at the spool, arm tension T):

    τ = τ_low(T) + (τ_raise(T) − τ_low(T))·w + clamp(b·ω_s + J·α_s, ±max_dynamic_nm)

* ``w = (σ + 1)/2`` where σ is a **reversal state** in [−1, 1]: it relaxes towards the direction the
  cable is about to move (+1 into the sheath towards the motor, −1 out), with a hysteresis on the
  predicted elevation velocity so that noise at rest never toggles it. While the sheath sticks at a
  turn, any motor tension inside the friction cone holds the cable, so switching to the coming
  direction's line *before* the cable moves is free; switching after it moved (the lagging velocity
  sign of the paper's blend) is what lets arm tension build up to breakaway on the old line.
* ``b·ω_s`` is the velocity-proportional drag of cable and motor (the "lines fanning out with speed"
  of the identification summary), with ω_s the spool velocity the arm's motion implies.
* ``J·α_s`` accelerates the rotor and spool with the arm, so the cable does not have to.

The friction law of the later code of the same group (Stribeck curve on cable velocity) adds a
breakaway term near zero velocity. It is deliberately not part of the command: near zero cable velocity
the sheath sticks and the arm tension is set by the cable's stretch, not by the motor, and a breakaway
boost at every turn pushes the command to the edge of the friction cone exactly where the spike comes
from. The reversal state handles the stick regime instead.

Elevation and velocity come from :mod:`bowden.model.elevation_estimator` (a Kalman filter that also
predicts across the IMU's latency). Parameters are identified by
:mod:`bowden.identify.dynamic` from the paper's bench protocol.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bowden.errors import ParameterError
from bowden.model.lines import CompensationLine
from bowden.validation import check_field, check_number


@dataclass(frozen=True, kw_only=True)
class DynamicFitStats:
    """How well the dynamic model was identified: standard errors and residuals per regime.

    ``regime_rms_nm`` maps a regime of the bench recording (``steady raising``, ``steady lowering``,
    ``ramps``, ``turns``) to the RMS torque residual of this model there, and ``paper_rms_nm`` to that
    of the paper's two lines on the same samples, so the gain of each term can be read per regime.
    """

    n: int
    viscous_se_nm_s_rad: float
    inertia_se_kg_m2: float
    regime_rms_nm: tuple[tuple[str, float], ...] = ()
    paper_rms_nm: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        if not (isinstance(self.n, int) and self.n >= 0):
            raise ParameterError(f"DynamicFitStats.n must be a non-negative integer, got {self.n!r}")
        check_field(self, "viscous_se_nm_s_rad", 0.0, math.inf)
        check_field(self, "inertia_se_kg_m2", 0.0, math.inf)
        for table in (self.regime_rms_nm, self.paper_rms_nm):
            for name, value in table:
                if not isinstance(name, str):
                    raise ParameterError(f"DynamicFitStats regime names must be strings, got {name!r}")
                check_number(value, f"DynamicFitStats regime {name!r}", 0.0)


@dataclass(frozen=True, kw_only=True)
class DynamicCompensation:
    """Parameters of the dynamic compensation (see the module docstring for the law).

    Parameters
    ----------
    raising, lowering
        Load-proportional friction lines without the velocity-dependent part (identified jointly
        with ``viscous_nm_s_rad``, so their intercepts are the Coulomb friction of motor and sheath).
    viscous_nm_s_rad
        Drag per spool velocity, Nm·s/rad, ≥ 0 (sheath drag times the spool radius², plus the motor's).
    inertia_kg_m2
        Rotor, gearbox and spool inertia at the spool, kg·m² (AK60-6 with spool ≈ 1.5e-3).
    imu_latency_s
        Age of the IMU's samples when they arrive; the estimator predicts across it. Range [0, 0.2] s.
        Too high costs little (the reversal is seen a little early); too low costs much (the old
        direction's line is held into the turn), so when unsure, err high.
    reversal_hysteresis_rad_s
        Predicted elevation speed beyond which the reversal state takes a new direction (0.07 rad/s,
        4°/s); seven times the estimator's predicted-velocity noise at rest (≈ 0.01 rad/s with the
        NGIMU's gyro), so that a wearer at rest never toggles it.
    reversal_time_s
        Time constant with which the reversal state moves to the new direction (a step in torque at
        a turn would excite the cable).
    max_dynamic_nm
        Bound on the drag and inertia terms together: a wrong velocity or acceleration estimate can
        never add more than this to the command.
    recommended, recommendation
        Whether the dynamic compensation is recommended over the paper's lines and the one line why:
        it is only where the study-like bench segment showed it beating the paper's with confidence
        on paired held-out strokes (the 95 % upper bound of its RMSE and onset peak over the paper's
        below 1; docs/dynamic_compensation.md, "Which compensation"); ``build_controller``
        uses the paper's lines by default when it is not. A model never validated says so.
        With ``recommended_cells`` it is the choice for supports the bench did not measure: dynamic
        only if it won every measured cell.
    recommended_cells
        The choice per (support, speed) cell the study-like segment measured: ``(support label, speed,
        dynamic?)`` with the label of :func:`support_label` ("pretension", "25", "50") and the speed's
        name ("V1"…). Empty (a model from before issue 28's per-cell rule): ``recommended`` everywhere.
        :meth:`recommended_for` reads it.
    """

    raising: CompensationLine
    lowering: CompensationLine
    viscous_nm_s_rad: float
    inertia_kg_m2: float
    imu_latency_s: float = 0.05
    reversal_hysteresis_rad_s: float = 0.07
    reversal_time_s: float = 0.01
    max_dynamic_nm: float = 0.6
    fit: DynamicFitStats | None = None
    recommended: bool = True
    recommendation: str = "not validated on the bench's study-like segment"
    recommended_cells: tuple[tuple[str, str, bool], ...] = ()

    def __post_init__(self) -> None:
        check_field(self, "viscous_nm_s_rad", 0.0, 1.0)
        check_field(self, "inertia_kg_m2", 0.0, 0.05)
        check_field(self, "imu_latency_s", 0.0, 0.2)
        check_field(self, "reversal_hysteresis_rad_s", 0.0, 2.0)
        check_field(self, "reversal_time_s", 1e-4, 1.0)
        check_field(self, "max_dynamic_nm", 0.0, 5.0)
        if not isinstance(self.recommended, bool) or not isinstance(self.recommendation, str):
            raise ParameterError("DynamicCompensation.recommended must be a bool and recommendation a string")
        for cell in self.recommended_cells:
            if not (isinstance(cell, tuple) and len(cell) == 3 and isinstance(cell[0], str)
                    and isinstance(cell[1], str) and isinstance(cell[2], bool)):
                raise ParameterError(
                    "DynamicCompensation.recommended_cells holds (support, speed, dynamic?) cells, "
                    f"got {cell!r}"
                )
        if self.raising.slope_m < self.lowering.slope_m:
            raise ParameterError(
                f"DynamicCompensation: the raising slope ({self.raising.slope_m:.5g} m) is below the "
                f"lowering slope ({self.lowering.slope_m:.5g} m); friction cannot explain that"
            )

    def recommended_for(self, support: float | str, speed: str | None = None) -> bool:
        """Whether the dynamic compensation is recommended at ``support`` and ``speed``.

        The measured cell's choice; with the speed unknown (``None``, or a speed the bench did not
        run), dynamic only if it won at every measured speed of that support; at a support the bench
        did not measure, :attr:`recommended` (dynamic only if it won every measured cell).
        """
        if not self.recommended_cells:
            return self.recommended
        label = support_label(support)
        by_speed = {cell_speed: dynamic for cell_label, cell_speed, dynamic in self.recommended_cells
                    if cell_label == label}
        if not by_speed:
            return self.recommended
        if speed in by_speed:
            return by_speed[speed]
        return all(by_speed.values())

    def torque_nm(
        self,
        tension_n: float,
        reversal_state: float,
        spool_velocity_rad_s: float = 0.0,
        spool_acceleration_rad_s2: float = 0.0,
    ) -> float:
        """Motor torque for an arm tension, reversal state σ ∈ [−1, 1] and spool motion (unclamped)."""
        weight = 0.5 * (max(-1.0, min(1.0, reversal_state)) + 1.0)
        lowering = self.lowering.torque_nm(tension_n)
        raising = self.raising.torque_nm(tension_n)
        dynamic = (
            self.viscous_nm_s_rad * spool_velocity_rad_s + self.inertia_kg_m2 * spool_acceleration_rad_s2
        )
        dynamic = max(-self.max_dynamic_nm, min(self.max_dynamic_nm, dynamic))
        return lowering + (raising - lowering) * weight + dynamic

    def friction_nm(self, tension_n: float, spool_velocity_rad_s: float) -> float:
        """Friction torque the model assigns to steady motion at ``spool_velocity_rad_s`` (for figures):
        the torque beyond the frictionless mean of the two lines."""
        state = 1.0 if spool_velocity_rad_s > 0.0 else -1.0 if spool_velocity_rad_s < 0.0 else 0.0
        mean = 0.5 * (self.raising.torque_nm(tension_n) + self.lowering.torque_nm(tension_n))
        return self.torque_nm(tension_n, state, spool_velocity_rad_s) - mean


def support_label(support: float | str) -> str:
    """The label of a support in :attr:`DynamicCompensation.recommended_cells`: ``"pretension"`` or the
    percentage rounded to a whole number (0.25 → ``"25"``)."""
    if isinstance(support, str):
        return support
    return f"{round(100.0 * float(support)):d}"
