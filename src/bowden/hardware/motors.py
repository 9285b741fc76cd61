"""The T-motor (CubeMars) AK family by name: each model's MIT-mode ranges, gear ratio and torque constant.

Every model below speaks the same MIT-mode frames (:mod:`bowden.hardware.ak60_codec`) with its own
field ranges, so one driver (:class:`~bowden.hardware.ak60.AK60Motor`) and one simulated peer
(:class:`~bowden.sim.peers.AK60Peer`) serve them all once they are given the model's
:class:`~bowden.hardware.ak60_codec.AK60Limits`. ``bowden run``/``serve``/``bench run``/``check``
take ``--motor NAME`` and ``--firmware VARIANT``.

Sources
-------
* MIT-mode ranges: CubeMars, *AK Series Actuator Driver Manual* V1.0.8, §5.3, the table of ranges per
  module (p. 50): position ±12.5 rad, Kp 0–500, Kd 0–5 for every model; velocity ±50 (AK10-9, AK70-10,
  AK80-9), ±45 (AK60-6), ±76 (AK80-6), ±8 rad/s (AK80-64); torque ±65, ±15, ±25, ±12, ±18, ±144 Nm.
  neurobionics/TMotorCANControl (``mit_can.py`` ``MIT_Params``, commit bb8d071) agrees except for
  the AK60-6's velocity (±50 rad/s), which some firmware uses; it and the ±9 Nm torque range of other
  public drivers are the AK60-6's other firmware variants (``ak60_codec.FIRMWARE_LIMITS``).
* Gear ratio: the number after the dash (CubeMars, *AK Series Dynamical Modular Instruction* §2.2:
  "AK80-9 … 9 stands for reduction ratio"). TMotorCANControl gives 80 for the AK80-64 (its KV, not its
  ratio); we follow the name.
* Torque constant (motor side, Nm/A, before the gear): the values TMotorCANControl quotes "from
  TMotor website" (``Kt_TMotor``). They are not used by the controller, which commands output
  torque; they are recorded for the lab's own current ↔ torque checks. Check them against your
  motor's datasheet.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Final

from bowden.errors import ParameterError
from bowden.hardware.ak60_codec import (
    DEFAULT_FIRMWARE,
    FIRMWARE_LIMITS,
    MOTOR_LIMITS,
    AK60Limits,
)

MANUAL_VARIANT: Final = "manual-v1.0.8"  # the ranges of the CubeMars manual V1.0.8 §5.3
DEFAULT_MOTOR: Final = "AK60-6"  # the paper's TDU


@dataclass(frozen=True, kw_only=True)
class AKMotorModel:
    """One AK-series model.

    Parameters
    ----------
    name
        Model name as CubeMars writes it ("AK70-10").
    gear_ratio
        Reduction of the integrated planetary gear (output turns per motor turn⁻¹).
    torque_constant_nm_per_a
        Motor-side torque constant (Nm/A), before the gear.
    firmware
        The firmware variants' MIT-mode field ranges, by name; ``default_firmware`` is one of them.
    """

    name: str
    gear_ratio: float
    torque_constant_nm_per_a: float
    firmware: Mapping[str, AK60Limits]
    default_firmware: str = MANUAL_VARIANT

    def __post_init__(self) -> None:
        if self.default_firmware not in self.firmware:
            raise ParameterError(f"{self.name}: default firmware {self.default_firmware!r} is not a variant")
        if not (self.gear_ratio > 0.0 and self.torque_constant_nm_per_a > 0.0):
            raise ParameterError(f"{self.name}: gear ratio and torque constant must be positive")

    @property
    def output_torque_constant_nm_per_a(self) -> float:
        """Output-shaft torque per ampere of q-axis current (gear losses not counted)."""
        return self.torque_constant_nm_per_a * self.gear_ratio

    def limits(self, firmware: str | None = None) -> AK60Limits:
        """The field ranges of ``firmware`` (default: the manual's) on this model.

        Raises
        ------
        ParameterError
            Naming ``--firmware`` and the model's variants when ``firmware`` is not one of them.
        """
        name = self.default_firmware if firmware is None else firmware
        try:
            return self.firmware[name]
        except KeyError:
            raise ParameterError(f"--firmware {name} is not a firmware variant of the {self.name} "
                                 f"(--motor); known: {', '.join(sorted(self.firmware))}") from None

    def describe_limits(self, firmware: str | None = None) -> str:
        """The ranges in one phrase ("±50 rad/s, ±25 Nm")."""
        limits = self.limits(firmware)
        return f"±{limits.velocity_rad_s:g} rad/s, ±{limits.torque_nm:g} Nm"


def _manual_only(name: str) -> dict[str, AK60Limits]:
    return {MANUAL_VARIANT: MOTOR_LIMITS[name]}


AK_MOTORS: Final[Mapping[str, AKMotorModel]] = {
    model.name: model
    for model in (
        AKMotorModel(name="AK10-9", gear_ratio=9.0, torque_constant_nm_per_a=0.16,
                     firmware=_manual_only("AK10-9")),
        AKMotorModel(name="AK60-6", gear_ratio=6.0, torque_constant_nm_per_a=0.068,
                     firmware=dict(FIRMWARE_LIMITS), default_firmware=DEFAULT_FIRMWARE),
        AKMotorModel(name="AK70-10", gear_ratio=10.0, torque_constant_nm_per_a=0.095,
                     firmware=_manual_only("AK70-10")),
        AKMotorModel(name="AK80-6", gear_ratio=6.0, torque_constant_nm_per_a=0.091,
                     firmware=_manual_only("AK80-6")),
        AKMotorModel(name="AK80-9", gear_ratio=9.0, torque_constant_nm_per_a=0.091,
                     firmware=_manual_only("AK80-9")),
        AKMotorModel(name="AK80-64", gear_ratio=64.0, torque_constant_nm_per_a=0.119,
                     firmware=_manual_only("AK80-64")),
    )
}

# Every variant name any model knows (the --firmware choices); a pair is checked by AKMotorModel.limits.
FIRMWARE_VARIANTS: Final = tuple(sorted({name for model in AK_MOTORS.values() for name in model.firmware}))


def motor_model(name: str) -> AKMotorModel:
    """The catalogue entry of ``name``.

    Raises
    ------
    ParameterError
        Naming ``--motor`` and the known models.
    """
    try:
        return AK_MOTORS[name]
    except KeyError:
        raise ParameterError(f"--motor {name} is not a known motor; known: {', '.join(AK_MOTORS)}") from None


def motor_limits(name: str, firmware: str | None = None) -> AK60Limits:
    """The MIT-mode field ranges of model ``name`` running ``firmware`` (default: the manual's)."""
    return motor_model(name).limits(firmware)
