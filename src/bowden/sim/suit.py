"""The simulated suit behind the hardware protocols: a motor, an IMU, a load cell and a clock.

``SimulatedSuit`` owns one :class:`~bowden.sim.plant.Plant` and one arm driver. Its ``motor``,
``elevation_sensor`` and ``tension_sensor`` implement :mod:`bowden.hardware.protocols`, so the runtime
loop cannot tell it from the real suit; its ``clock`` advances the physics instead of sleeping, and
``advance_to`` lets simulated CAN/OSC peers run it in wall time.
"""

from __future__ import annotations

import math
from types import TracebackType
from typing import Self

import numpy as np

from bowden.errors import HardwareError, ParameterError
from bowden.hardware.protocols import ElevationSample, MotorState, TensionSample
from bowden.sim import _kernels as k
from bowden.sim.arm import ArmDriver, PrescribedArm
from bowden.sim.parameters import SuitParameters, check_seed
from bowden.sim.plant import Plant, PlantState

# Winding temperature: first-order model, copper loss ∝ torque². The AK60-6's ≈ 0.45 Nm/A at the
# output and ≈ 0.3 Ω phase resistance give ≈ 2 W per Nm²; thermal resistance and time constant are
# typical of a 60 mm outrunner in a closed housing (not published for this motor).
AMBIENT_TEMPERATURE_C = 25.0
COPPER_LOSS_W_PER_NM2 = 2.0
THERMAL_RESISTANCE_K_W = 2.5
THERMAL_TIME_CONSTANT_S = 300.0


class SimulatedSuit:
    """One simulated suit and the arm it is worn on (or mounted on).

    Parameters
    ----------
    parameters
        The suit (defaults: the paper's).
    arm
        What moves the arm: :class:`PrescribedArm`, :class:`MannequinArm` or :class:`ParticipantArm`
        (default: an arm held at 20°).
    seed
        Seed of the sensor noise and of the participant's motor noise.
    initial_tension_n
        Cable tension at time 0 (the suit starts at rest with the sheath stuck).

    Attributes
    ----------
    motor, elevation_sensor, tension_sensor, clock
        The hardware-protocol faces of the suit.
    """

    def __init__(
        self,
        parameters: SuitParameters | None = None,
        arm: ArmDriver | None = None,
        *,
        seed: int = 0,
        initial_tension_n: float = 5.0,
    ) -> None:
        check_seed(seed)
        self.parameters = parameters if parameters is not None else SuitParameters()
        self.arm: ArmDriver = arm if arm is not None else PrescribedArm.hold(math.radians(20.0))
        self.plant = Plant(
            self.parameters,
            self.arm.arm_parameters,
            elevation_rad=self.arm.initial_elevation_rad(),
            tension_n=initial_tension_n,
        )
        self._rng = np.random.default_rng(seed)
        self._time_s = 0.0
        self.motor = SimulatedMotor(self)
        self.elevation_sensor = SimulatedImu(self)
        self.tension_sensor = SimulatedLoadCell(self)
        self.clock = SimulatedClock(self)

    @property
    def time_s(self) -> float:
        """Simulated time (s): the latest time the suit was advanced to."""
        return self._time_s

    def advance_to(self, time_s: float) -> None:
        """Integrate the plant up to ``time_s`` with the motor's current command (never backwards)."""
        if not math.isfinite(time_s):
            raise ParameterError(f"advance_to needs a finite time, got {time_s!r}")
        if time_s <= self._time_s:
            return
        dt = self.plant.substep_s
        target = math.floor(time_s / dt + 1e-9)
        n = target - self.plant.steps_done
        if n > 0:
            first = self.plant.steps_done + 1
            times = np.asarray((first + np.arange(n)) * dt, dtype=np.float64)
            arm_a, arm_b = self.arm.inputs(times, self._rng)
            mode, command = self.motor.plant_command()
            record = self.plant.integrate(
                n,
                motor_mode=mode,
                command=command,
                arm_mode=self.arm.mode,
                arm_a=arm_a,
                arm_b=arm_b,
                human=self.arm.human(),
            )
            self.motor.heat(record[:, k.R_MOTOR_TAU], n * dt)
            self.elevation_sensor.sample(times, record)
            self.tension_sensor.sample(times, record)
        self._time_s = time_s

    def true_state(self) -> PlantState:
        """The true plant state (anchor tension, arm angle and velocity, sheath stick/slip...)."""
        return self.plant.state()


def _latest_sample_index(times: np.ndarray, rate_hz: float, last: int) -> tuple[int, int]:
    """Newest sample number ≤ the last step time, and the step whose time is closest below it."""
    newest = math.floor(times[-1] * rate_hz + 1e-9)
    if newest <= last:
        return newest, -1
    sample_time = newest / rate_hz
    row = int(np.searchsorted(times, sample_time + 1e-12, side="right")) - 1
    return newest, max(row, 0)


class SimulatedImu:
    """Upper-arm IMU: elevation and elevation speed at its sample rate, with noise, bias and latency
    (a sample stamped ``t`` becomes readable at ``t`` and shows the arm as it was at ``t − latency``)."""

    def __init__(self, suit: SimulatedSuit) -> None:
        self._suit = suit
        self._latest: ElevationSample | None = None
        self._last_index = -1
        x = suit.plant.state_vector
        self._history_t = np.array([0.0])
        self._history_th = np.array([float(x[k.X_ARM_TH])])
        self._history_thd = np.array([float(x[k.X_ARM_THD])])

    def _remember(self, times: np.ndarray, record: np.ndarray) -> None:
        keep_s = self._suit.parameters.imu.latency_s + 0.05
        t = np.concatenate([self._history_t, times])
        first = int(np.searchsorted(t, t[-1] - keep_s))
        self._history_t = t[first:]
        self._history_th = np.concatenate([self._history_th, record[:, k.R_TH]])[first:]
        self._history_thd = np.concatenate([self._history_thd, record[:, k.R_THD]])[first:]

    def sample(self, times: np.ndarray, record: np.ndarray) -> None:
        imu = self._suit.parameters.imu
        self._remember(times, record)
        index, row = _latest_sample_index(times, imu.sample_rate_hz, self._last_index)
        if row < 0:
            return
        self._last_index = index
        sample_time = index / imu.sample_rate_hz
        seen = sample_time - imu.latency_s
        th = float(np.interp(seen, self._history_t, self._history_th))
        thd = float(np.interp(seen, self._history_t, self._history_thd))
        rng = self._suit._rng
        self._latest = ElevationSample(
            time_s=sample_time,
            elevation_rad=th
            + imu.elevation_bias_rad
            + imu.elevation_noise_rad * float(rng.standard_normal()),
            elevation_velocity_rad_s=thd
            + imu.velocity_bias_rad_s
            + imu.velocity_noise_rad_s * float(rng.standard_normal()),
        )

    def read(self) -> ElevationSample | None:
        return self._latest

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        return None


class SimulatedLoadCell:
    """Load cell at the anchor: tension at its sample rate, with noise and offset."""

    def __init__(self, suit: SimulatedSuit) -> None:
        self._suit = suit
        self._latest: TensionSample | None = None
        self._last_index = -1
        self.failure: str | None = None  # the simulated load cell is never lost

    def sample(self, times: np.ndarray, record: np.ndarray) -> None:
        cell = self._suit.parameters.load_cell
        index, row = _latest_sample_index(times, cell.sample_rate_hz, self._last_index)
        if row < 0:
            return
        self._last_index = index
        noise = cell.noise_n * float(self._suit._rng.standard_normal())
        self._latest = TensionSample(
            time_s=index / cell.sample_rate_hz,
            tension_n=float(record[row, k.R_T_OUT]) + cell.offset_n + noise,
        )

    def read(self) -> TensionSample | None:
        return self._latest

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        return None


class SimulatedMotor:
    """The AK60-6 as the runtime sees it: torque commands in, state replies out (output-shaft units).

    The reported torque is what the driver estimates from its current with its nominal torque
    constant, i.e. the delivered torque divided by ``torque_constant_ratio``; commands are held until
    the next one. ``command_impedance`` is the MIT-mode command the simulated CAN peer forwards.
    """

    def __init__(self, suit: SimulatedSuit) -> None:
        self._suit = suit
        self._enabled = False
        self._mode = k.MOTOR_OFF
        self._command = np.zeros(5)
        self._zero_rad = 0.0
        self._temperature_c = AMBIENT_TEMPERATURE_C

    @property
    def enabled(self) -> bool:
        return self._enabled

    def plant_command(self) -> tuple[int, np.ndarray]:
        """Motor mode and command vector for the plant (limp while disabled)."""
        if not self._enabled:
            return k.MOTOR_OFF, self._command
        return self._mode, self._command

    def heat(self, delivered_torque_nm: np.ndarray, duration_s: float) -> None:
        """Advance the winding temperature over ``duration_s`` with the delivered torques."""
        loss_w = COPPER_LOSS_W_PER_NM2 * float(np.mean(delivered_torque_nm**2))
        steady = AMBIENT_TEMPERATURE_C + THERMAL_RESISTANCE_K_W * loss_w
        self._temperature_c += (steady - self._temperature_c) * (
            1.0 - math.exp(-duration_s / THERMAL_TIME_CONSTANT_S)
        )

    def state(self) -> MotorState:
        x = self._suit.plant.state_vector
        return MotorState(
            time_s=self._suit.time_s,
            position_rad=float(x[k.X_SPOOL_Q]) - self._zero_rad,
            velocity_rad_s=float(x[k.X_SPOOL_W]),
            torque_nm=k.reported_torque_nm(x, self._suit.plant.vector),
            temperature_c=self._temperature_c,
            error_code=0,
        )

    def enable(self) -> MotorState:
        self._enabled = True
        self._mode = k.MOTOR_TORQUE
        self._command = np.zeros(5)
        return self.state()

    def disable(self) -> None:
        self._enabled = False
        self._mode = k.MOTOR_OFF
        self._command = np.zeros(5)

    def set_zero(self) -> None:
        self._zero_rad = float(self._suit.plant.state_vector[k.X_SPOOL_Q])

    def _require_enabled(self) -> None:
        if not self._enabled:
            raise HardwareError("simulated motor is not in motor mode: call enable() first")

    def command_torque(self, torque_nm: float) -> MotorState:
        self._require_enabled()
        if not math.isfinite(torque_nm):
            raise HardwareError(f"torque command must be finite, got {torque_nm!r}")
        self._mode = k.MOTOR_TORQUE
        self._command = np.array([torque_nm, 0.0, 0.0, 0.0, 0.0])
        return self.state()

    def command_impedance(
        self,
        position_rad: float,
        velocity_rad_s: float,
        kp_nm_rad: float,
        kd_nms_rad: float,
        torque_ff_nm: float,
    ) -> MotorState:
        """MIT-mode command ``τ = kp·(p − position) + kd·(v − velocity) + τ_ff``, evaluated by the motor
        at every plant step (as the driver's inner loop does); ``position_rad`` relative to the zero."""
        self._require_enabled()
        values = (position_rad, velocity_rad_s, kp_nm_rad, kd_nms_rad, torque_ff_nm)
        if not all(math.isfinite(v) for v in values) or kp_nm_rad < 0.0 or kd_nms_rad < 0.0:
            raise HardwareError(f"impedance command must be finite with kp, kd >= 0, got {values!r}")
        self._mode = k.MOTOR_IMPEDANCE
        self._command = np.array(
            [position_rad + self._zero_rad, velocity_rad_s, kp_nm_rad, kd_nms_rad, torque_ff_nm]
        )
        return self.state()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.disable()


class SimulatedClock:
    """Simulated time: ``sleep_until`` advances the suit's physics to the deadline."""

    def __init__(self, suit: SimulatedSuit) -> None:
        self._suit = suit

    def now(self) -> float:
        return self._suit.time_s

    def sleep_until(self, deadline_s: float) -> None:
        self._suit.advance_to(deadline_s)
