"""Parameters of the simulated suit, each with its source and its valid range.

Defaults reproduce the paper's suit (Bardi et al., sensorless tension control of a cable-driven
exosuit) as far as it is published; where the paper is silent the value comes from docs/simulation.md (a
plant that behaves like the paper's suit) or from the device's manual, and the docstring says so.
Every class is a frozen keyword-only dataclass validated on construction: a value outside its range
raises :class:`bowden.errors.ParameterError` naming the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from bowden.errors import ParameterError
from bowden.hardware.ads1115 import FULL_SCALE_V
from bowden.model import CuffGeometry
from bowden.sim.plant_structure import PlantStructure
from bowden.validation import check_field

MAX_SEED = 2**32 - 1  # numpy seeds are unsigned; one 32-bit word keeps them portable


def check_seed(seed: object, name: str = "seed") -> None:
    """Refuse a seed numpy would reject (negative, not an integer) with an error that names it."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
        raise ParameterError(f"{name} must be an integer in [0, {MAX_SEED}], got {seed!r}")


@dataclass(frozen=True, kw_only=True)
class MotorParameters:
    """The tendon driver unit: AK60-6 quasi-direct-drive motor and its spool, output-shaft units.

    Parameters
    ----------
    spool_radius_m
        Pulley radius; paper: 70 mm diameter PLA pulley → 0.035 m. Range (0.005, 0.2].
    rotor_inertia_kgm2
        Rotor + gearbox + spool inertia reflected to the output shaft; ≈ 1.5e-3. No
        AK60-6 value is published that we could find; its larger sibling AK80-6 (same 6:1 gear) has a
        rotor inertia of 6.07e-5 kg·m² (T-motor manual, quoted in the DFKI double-pendulum
        documentation; identified there as 6.1e-5–8.8e-5), i.e. 2.2e-3–3.2e-3 kg·m² after the gear
        (× 6²). The AK60-6 is the smaller motor (≈ 0.9e-3 when scaled by mass and diameter), and the
        70 mm PLA spool adds ≈ 3e-5, so 1.5e-3 sits in the plausible band and values above ≈ 3e-3 are
        not supported. Range (1e-5, 0.05].
    coulomb_friction_nm
        Coulomb friction of motor and gearbox at the output; 0.05–0.25 Nm (an assumed range around
        the DFKI identification below). 0.08 Nm,
        the low end of the 0.08–0.19 Nm DFKI identified on the AK80-6 with a pendulum bearing: the
        paper's pretension RMSE at 60 °/s (2.75 N) leaves little room for the ≈ R⁻¹·τ_c error it
        causes wherever the blend of the two lines is undecided, and at 0.06 Nm the largest
        pretension error at 180 °/s is the sheath drag of fast lowering, no longer the spike after
        the turn that the paper reports. Range [0, 1].
    viscous_friction_nms_rad
        Viscous friction at the output: 0.005 Nm·s/rad, within the 0.004–0.011 Nm·s/rad DFKI identified
        on the AK80-6 (double-pendulum ``model_parameters`` files, tmotors_v1.0/v2.0). Range [0, 0.1].
    current_loop_time_constant_s
        First-order lag of the driver's current (torque) loop; ≈ 1 ms (an assumption: no AK60-6 value is
        published). Range (1e-5, 0.05].
    torque_constant_ratio
        Delivered torque per commanded (and per reported) torque: the true torque constant over the one
        the driver assumes. The AK60-6 constant is uncertain within 0.068–0.087 Nm/A (CubeMars' data
        sheet against its manual);
        ±15 % is the largest single source of error. Range [0.5, 1.5].
    torque_limit_nm
        Saturation of the driver's torque (its current times the constant it assumes, as it reports it);
        the torque delivered at that current is this times ``torque_constant_ratio`` and the warm
        constant's drift. AK60-6 peak 9 Nm (CubeMars AK60-6 specification). Range (0, 50].
    """

    spool_radius_m: float = 0.035
    rotor_inertia_kgm2: float = 1.5e-3
    coulomb_friction_nm: float = 0.08
    viscous_friction_nms_rad: float = 0.005
    current_loop_time_constant_s: float = 1.0e-3
    torque_constant_ratio: float = 1.0
    torque_limit_nm: float = 9.0

    def __post_init__(self) -> None:
        check_field(self, "spool_radius_m", 0.005, 0.2, low_open=True)
        check_field(self, "rotor_inertia_kgm2", 1e-5, 0.05, low_open=True)
        check_field(self, "coulomb_friction_nm", 0.0, 1.0)
        check_field(self, "viscous_friction_nms_rad", 0.0, 0.1)
        check_field(self, "current_loop_time_constant_s", 1e-5, 0.05, low_open=True)
        check_field(self, "torque_constant_ratio", 0.5, 1.5)
        check_field(self, "torque_limit_nm", 0.0, 50.0, low_open=True)


@dataclass(frozen=True, kw_only=True)
class SheathParameters:
    """Bowden sheath friction as one lumped bend (supplement of the paper, eq. S1–S5).

    The normal force on the cable is ``sin(φ/2)·(T_in + T_out)``; the friction coefficient times
    ``sin(φ/2)`` is the single number ``k`` of the paper's transmission law, so the parameters are
    given directly as ``k`` values.

    Parameters
    ----------
    kinetic_coefficient
        ``k = μ_k·sin(φ/2)`` while the cable slides fast, on the identification bench. docs/simulation.md:
        0.05–0.15, the paper's 50 % support RMSE between 0.10 and 0.15. 0.10 here: with the sheath
        drag below, larger values make the slow movements' errors at 50 % support exceed the
        medium ones' (the hysteresis band at each reversal scales with k and lasts longest at
        60 °/s), which the paper does not show (docs/simulation.md). Range [0, 0.5].
    static_to_kinetic_ratio
        Breakaway over kinetic coefficient; 1.0–1.6 assumed. Range [1, 3], and the static
        coefficient must stay below 0.6 so that the sheath can still transmit tension.
    stribeck_velocity_m_s
        Slip speed over which friction falls from static to kinetic, ``k(v) = k_k + (k_s − k_k)·
        exp(−(v/v_s)²)`` (Stribeck curve, Olsson et al. 1998, Eur J Control 4:176). docs/simulation.md:
        ≈ 3 mm/s. Range (1e-5, 0.1].
    stick_velocity_m_s
        Slip speed below which a sliding cable that is inside the static friction cone sticks again.
        A numerical threshold of the stick–slip switch, far below the Stribeck velocity. Range
        (0, 0.01].
    viscous_coefficient_ns_m
        Velocity-proportional drag of the cable in the sheath, ``c_v`` in ``T_in − T_out =
        σ·k·(T_in + T_out) + c_v·v``, independent of the normal force (the viscous term of the
        standard friction map, Olsson et al. 1998; LuGre's σ₂, Canudas de Wit et al. 1995, IEEE TAC
        40:419, used for tendon transmissions by Palli & Melchiorri 2014, Mechatronics 24:108;
        tendon–sheath friction models with velocity- and acceleration-dependent terms: Do,
        Tjahjowidodo, Lau & Phee 2015, Mech Syst Signal Process 60–61:770).
        Physically the shear of the lubricant or liner between cable and sheath, ``η·π·d·L/h``
        (Newton's law of viscosity), which spans ≈ 1–100 N·s/m for a 1.5 mm cable in ≈ 1 m of sheath
        (η 0.1–1 Pa·s, gap 50–200 µm). No measurement of the paper's sheath exists. 25 N·s/m is
        calibrated, jointly with ``kinetic_coefficient``, on the study's speed trend: with it the
        simulated tension error grows with speed in every condition for cohort seeds 0–4, with
        0.07–0.35 N between 60 and 120 °/s at 50 % support (paper 0.32 N); 24 N·s/m leaves only
        0.02–0.03 N there for seeds 0 and 2, 20 N·s/m inverts it (docs/simulation.md). The bench
        does not contradict it: lowering R² 0.9992 in fitlm's robust definition (the paper's 0.9906
        most likely is that one: MATLAB fitlm with 'RobustOpts') and 0.9896 as OLS R². It moves only
        the intercepts
        of the identified lines, by ``R²·c_v·|ω|/(1 ∓ k)``, never their slopes. Range [0, 100].
    """

    kinetic_coefficient: float = 0.10
    static_to_kinetic_ratio: float = 1.3
    stribeck_velocity_m_s: float = 3.0e-3
    stick_velocity_m_s: float = 1.0e-4
    viscous_coefficient_ns_m: float = 25.0

    def __post_init__(self) -> None:
        check_field(self, "kinetic_coefficient", 0.0, 0.5)
        check_field(self, "viscous_coefficient_ns_m", 0.0, 100.0)
        check_field(self, "static_to_kinetic_ratio", 1.0, 3.0)
        check_field(self, "stribeck_velocity_m_s", 1e-5, 0.1, low_open=True)
        check_field(self, "stick_velocity_m_s", 0.0, 0.01, low_open=True)
        if self.static_coefficient >= 0.6:
            raise ParameterError(
                "SheathParameters: kinetic_coefficient * static_to_kinetic_ratio = "
                f"{self.static_coefficient:.3f} must stay below 0.6"
            )

    @property
    def static_coefficient(self) -> float:
        """Breakaway ``k_s = μ_s·sin(φ/2)``."""
        return self.kinetic_coefficient * self.static_to_kinetic_ratio


@dataclass(frozen=True, kw_only=True)
class TransmissionParameters:
    """Elastic parts of the transmission: the cable on the motor side and the soft distal segment.

    Parameters
    ----------
    cable_stiffness_n_m
        Spool to sheath exit: Dyneema cable and the sheath's axial compliance. ≈ 3e4 N/m (an
        assumption: not published for the paper's suit).
        Range [1e3, 1e6].
    distal_stiffness_n_m
        Sheath exit to the arm anchor: cable, textile cuff and soft tissue. 2e3–1e4 N/m (an assumed
        range for textile and tissue).
        Range [200, 1e5].
    distal_damping_ns_m
        Damping of the distal segment (textile and tissue are lossy). Not published; 600 N·s/m is
        about a third of critical for a 0.5 kg·m² arm on a 0.1 m lever. Range [0, 5000].
    """

    cable_stiffness_n_m: float = 3.0e4
    distal_stiffness_n_m: float = 8.0e3
    distal_damping_ns_m: float = 600.0

    def __post_init__(self) -> None:
        check_field(self, "cable_stiffness_n_m", 1e3, 1e6)
        check_field(self, "distal_stiffness_n_m", 200.0, 1e5)
        check_field(self, "distal_damping_ns_m", 0.0, 5000.0)


@dataclass(frozen=True, kw_only=True)
class ImuParameters:
    """The upper-arm IMU (NGIMU): elevation from orientation, elevation speed from the gyroscope.

    Parameters
    ----------
    sample_rate_hz
        Output rate of the elevation sample (NGIMU rates are configurable up to 1 kHz). Range [10, 2000].
    elevation_noise_rad
        White noise on the elevation, 1 σ; NGIMU static accuracy is about 0.5°. Range [0, 0.1].
    elevation_bias_rad
        Constant offset of the elevation (strap placement, calibration pose). Range [−0.5, 0.5].
    velocity_noise_rad_s
        White noise on the elevation speed, 1 σ (gyroscope noise over its bandwidth). Range [0, 1].
    velocity_bias_rad_s
        Constant gyroscope bias projected on the elevation axis. Range [−0.5, 0.5].
    latency_s
        Age of a sample when the controller gets it: the IMU's orientation filter plus the OSC/UDP
        link over WiFi (tens of ms for the NGIMU; not reported in the paper). A late velocity keeps
        the friction compensation on the old direction's line after a reversal. Range [0, 0.2].
    """

    sample_rate_hz: float = 400.0
    elevation_noise_rad: float = math.radians(0.3)
    elevation_bias_rad: float = math.radians(0.5)
    velocity_noise_rad_s: float = math.radians(1.5)
    velocity_bias_rad_s: float = math.radians(0.3)
    latency_s: float = 0.05

    def __post_init__(self) -> None:
        check_field(self, "sample_rate_hz", 10.0, 2000.0)
        check_field(self, "latency_s", 0.0, 0.2)
        check_field(self, "elevation_noise_rad", 0.0, 0.1)
        check_field(self, "elevation_bias_rad", -0.5, 0.5)
        check_field(self, "velocity_noise_rad_s", 0.0, 1.0)
        check_field(self, "velocity_bias_rad_s", -0.5, 0.5)


@dataclass(frozen=True, kw_only=True)
class LoadCellParameters:
    """The load cell at the anchor (Futek LSB201 + amplifier + 16-bit ADS1115).

    Parameters
    ----------
    sample_rate_hz
        ADS1115 continuous-mode rate; its fastest is 860 SPS. Range [8, 2000].
    noise_n
        White noise, 1 σ. Range [0, 5].
    offset_n
        Zero offset left after taring. Range [−10, 10].
    adc_full_scale_v
        The ADS1115's full scale (V), one of its PGA settings (±6.144 … ±0.256 V); the driver's
        default ±4.096 V. The reading is a 16-bit code of it (0.125 mV, 0.0125 N at 100 N/V).
    adc_offset_v, gain_n_per_v
        The amplifier's output at no load (V) and the calibration (N/V): tension = (volts − offset) ·
        gain, as the driver computes; the simulated wire path's 0.05 V and 100 N/V. Offset range
        [−1, 1] V, gain (0, 1e4].
    """

    sample_rate_hz: float = 860.0
    noise_n: float = 0.15
    offset_n: float = 0.0
    adc_full_scale_v: float = 4.096
    adc_offset_v: float = 0.05
    gain_n_per_v: float = 100.0

    def __post_init__(self) -> None:
        check_field(self, "sample_rate_hz", 8.0, 2000.0)
        check_field(self, "noise_n", 0.0, 5.0)
        check_field(self, "offset_n", -10.0, 10.0)
        check_field(self, "adc_offset_v", -1.0, 1.0)
        check_field(self, "gain_n_per_v", 0.0, 1e4, low_open=True)
        if self.adc_full_scale_v not in FULL_SCALE_V:
            raise ParameterError(
                "LoadCellParameters.adc_full_scale_v must be an ADS1115 full scale "
                f"{sorted(set(FULL_SCALE_V))}, got {self.adc_full_scale_v!r}"
            )


@dataclass(frozen=True, kw_only=True)
class ArmParameters:
    """A rigid arm about the shoulder, driven by a torque (mannequin motor or muscles).

    Parameters
    ----------
    inertia_kgm2
        Moment of inertia about the shoulder including any hand load. Human arms with 0.5 kg in the
        hand: 0.45–0.65 kg·m² (de Leva 1996 segments, J Biomech 29:1223); the mannequin's lighter arm
        defaults here. Range
        (1e-3, 5].
    gravity_torque_nm
        Gravity torque with the arm horizontal (90°); the arm's gravity torque is this times sin θ.
        The mannequin's motor carries its own arm's weight, hence 0. Range [0, 50].
    damping_nms_rad
        Passive viscous damping of the joint. Range [0, 10].
    min_elevation_rad, max_elevation_rad
        Soft joint stops; the cuff geometry needs the arm below the cable exit (docs/design.md, "Cuff
        geometry").
    """

    inertia_kgm2: float = 0.08
    gravity_torque_nm: float = 0.0
    damping_nms_rad: float = 0.05
    min_elevation_rad: float = 0.0
    max_elevation_rad: float = math.radians(140.0)

    def __post_init__(self) -> None:
        check_field(self, "inertia_kgm2", 1e-3, 5.0, low_open=True)
        check_field(self, "gravity_torque_nm", 0.0, 50.0)
        check_field(self, "damping_nms_rad", 0.0, 10.0)
        check_field(self, "min_elevation_rad", -0.5, math.pi)
        check_field(self, "max_elevation_rad", -0.5, math.pi)
        if self.max_elevation_rad <= self.min_elevation_rad:
            raise ParameterError("ArmParameters.max_elevation_rad must exceed min_elevation_rad")


@dataclass(frozen=True, kw_only=True)
class SuitParameters:
    """Everything the plant needs, with the integration step.

    Parameters
    ----------
    motor, sheath, transmission, geometry, imu, load_cell
        The parts; ``geometry`` is the cuff geometry shared with the controller (docs/design.md, "Cuff
        geometry").
    structure
        Structural variants of the friction and motor physics (:mod:`bowden.sim.plant_structure`);
        the default is the nominal plant.
    substep_s
        Fixed integration step of the plant. Every stiff part (cable on the rotor, current loop,
        sheath node, friction) is integrated implicitly; the arm on the distal spring is explicit and
        stays stable up to 0.5 ms over every documented range (stiffest distal segment on the
        lightest arm). Range [1e-5, 5e-4].
    """

    motor: MotorParameters = field(default_factory=MotorParameters)
    sheath: SheathParameters = field(default_factory=SheathParameters)
    transmission: TransmissionParameters = field(default_factory=TransmissionParameters)
    geometry: CuffGeometry = field(default_factory=CuffGeometry)
    imu: ImuParameters = field(default_factory=ImuParameters)
    load_cell: LoadCellParameters = field(default_factory=LoadCellParameters)
    substep_s: float = 2.5e-4
    structure: PlantStructure = field(default_factory=PlantStructure)

    def __post_init__(self) -> None:
        expected = {
            "motor": MotorParameters,
            "sheath": SheathParameters,
            "transmission": TransmissionParameters,
            "geometry": CuffGeometry,
            "imu": ImuParameters,
            "load_cell": LoadCellParameters,
            "structure": PlantStructure,
        }
        for f in fields(self):
            kind = expected.get(f.name)
            if kind is not None and not isinstance(getattr(self, f.name), kind):
                raise ParameterError(f"SuitParameters.{f.name} must be a {kind.__name__}")
        check_field(self, "substep_s", 1e-5, 5e-4)
