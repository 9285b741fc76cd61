"""Where a trial's devices come from: the interface, and the simulated suit paced to wall time.

The trial manager asks a :class:`SuitBackend` for the devices of one trial and gets an
:class:`OpenSuit` (motor, IMU, optional load cell, clock, and how to close them). The real suit
(AK60-6 over CAN, NGIMU over OSC) is a :class:`ContextBackend` around the device opener that
``bowden run`` uses too (``bowden serve --backend can``); the simulated suit is the other, and
:class:`CommandLineBackend` stands for the one trial of ``bowden run --serve``. A simulated trial
runs the same :class:`bowden.runtime.ControlLoop` on :class:`bowden.sim.SimulatedSuit`, with a
virtual participant following the reference shown, but paced to the wall clock so that a person can
watch it: :class:`WallPacedClock` integrates the physics to each deadline at once, then waits until
that much wall time has passed.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass, field
from typing import Protocol

from bowden.contracts import BACKEND_SIM
from bowden.errors import ConflictError, ParameterError
from bowden.hardware.lsl_imu import parse_imu
from bowden.hardware.motors import DEFAULT_MOTOR, motor_model
from bowden.hardware.protocols import Clock, ElevationSensor, Motor, TensionSensor
from bowden.sim.arm import ParticipantArm, PrescribedArm
from bowden.sim.parameters import check_seed
from bowden.sim.participants import ExpectedAssistance, VirtualParticipant
from bowden.sim.peers.wall_time import WallTimePlant
from bowden.sim.peers.warm_up import warm_up_suit
from bowden.sim.suit import SimulatedSuit
from bowden.web.trial_setup import TrialSetup


def _nothing() -> None:
    return None


@dataclass
class OpenSuit:
    """The devices of one trial.

    Attributes
    ----------
    motor, elevation_sensor, clock, tension_sensor
        What the control loop drives and reads.
    description
        One line for the console and the trial's metadata ("simulated suit", "AK60-6 on can0"...).
    devices
        What the trial's metadata records of the hardware: ``motor_model``, ``motor_firmware`` and
        ``imu`` (``ngimu`` or ``lsl:NAME``), so the store says which actuator and IMU a trial ran on.
    health
        Backend-specific health figures for the console (e.g. wall-clock lag of a simulation).
    close
        Releases the devices after the loop has left motor mode.
    """

    motor: Motor
    elevation_sensor: ElevationSensor
    clock: Clock
    tension_sensor: TensionSensor | None = None
    description: str = ""
    devices: dict[str, str] = field(default_factory=dict)
    health: Callable[[], dict[str, float]] = field(default=dict)
    close: Callable[[], None] = field(default=_nothing)


class SuitBackend(Protocol):
    """Opens the suit for one trial."""

    @property
    def name(self) -> str:
        """Short name for the console and the trial metadata ("sim", "can")."""
        ...

    def open(self, setup: TrialSetup) -> OpenSuit: ...


class ContextBackend:
    """A backend from a context manager that yields one trial's devices and closes them on exit.

    This is how ``bowden serve --backend can`` serves the real suit: the device opener of
    ``bowden run`` (AK60-6 and NGIMU, optional load cell) is a context manager; wrapped so that it
    yields an :class:`OpenSuit`, each trial opens the suit (IMU calibration included) and closes it
    when the loop has left motor mode.

    Parameters
    ----------
    name
        Short name, one of ``contracts.BACKEND_*`` (the analysis reads it to tell simulated from
        measured trials).
    opener
        Called with the trial's setup; returns the context manager.
    """

    def __init__(self, name: str, opener: Callable[[TrialSetup], AbstractContextManager[OpenSuit]]) -> None:
        self._name = name
        self._opener = opener

    @property
    def name(self) -> str:
        return self._name

    def open(self, setup: TrialSetup) -> OpenSuit:
        stack = ExitStack()
        try:
            suit = stack.enter_context(self._opener(setup))
        except BaseException:
            stack.close()
            raise
        close_devices = suit.close

        def close() -> None:
            try:
                close_devices()
            finally:
                stack.close()

        suit.close = close
        return suit


@dataclass(frozen=True)
class CommandLineBackend:
    """The suit of ``bowden run --serve``: its one trial is started from the command line.

    The browsers watch that trial (and the console can stop it), but the console cannot start
    another: :meth:`open` refuses, and the refusal reaches the console as a 409 that says why.

    Parameters
    ----------
    name
        The backend of the run ("sim", "can").
    """

    name: str

    def open(self, setup: TrialSetup) -> OpenSuit:
        raise ConflictError(
            f"this server shows the trial of 'bowden run --backend {self.name}', which the command line "
            "starts; to start trials from the console, use 'bowden serve'"
        )


TIME_SCALE_RANGE = (0.05, 100.0)  # simulated s per wall s: slower than this is useless, faster not paced


def check_time_scale(time_scale: float) -> None:
    low, high = TIME_SCALE_RANGE
    if isinstance(time_scale, bool) or not (math.isfinite(time_scale) and low <= time_scale <= high):
        raise ParameterError(f"time_scale must be in [{low:g}, {high:g}], got {time_scale!r}")


class WallPacedClock:
    """A simulated clock slowed to wall time.

    ``now`` is the inner (simulated) time, so the loop and the sensors' time stamps agree;
    ``sleep_until`` advances the simulation to the deadline, then sleeps until the same amount of
    wall time (divided by ``time_scale``) has passed since the first call.

    Parameters
    ----------
    inner
        The simulated clock (``SimulatedSuit.clock``).
    time_scale
        Simulated seconds per wall second (1 = real time).
    wall, sleep
        The wall clock and its sleep (injected for tests).
    """

    def __init__(
        self,
        inner: Clock,
        *,
        time_scale: float = 1.0,
        wall: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        check_time_scale(time_scale)
        self.inner = inner
        self.time_scale = time_scale
        self._wall = wall
        self._sleep = sleep
        self._origin: tuple[float, float] | None = None
        self.worst_lag_s = 0.0  # how far the simulation fell behind the wall clock at a deadline

    def now(self) -> float:
        return self.inner.now()

    def sleep_until(self, deadline_s: float) -> None:
        if self._origin is None:
            self._origin = (self._wall(), self.inner.now())
        self.inner.sleep_until(deadline_s)
        wall0, sim0 = self._origin
        target = wall0 + (deadline_s - sim0) / self.time_scale
        remaining = target - self._wall()
        if remaining > 0.0:
            self._sleep(remaining)
        elif -remaining > self.worst_lag_s:
            self.worst_lag_s = -remaining


LSL_MAX_TIME_SCALE = 5.0  # the simulated LSL IMU streams at most 1 kHz of wall time: 200 Hz simulated
_LSL_SIM_RATE_HZ = 200.0  # the simulated IMU's rate in simulated time (the NGIMU's of bowden run)
_CALIBRATION_S = 0.3  # the arm-down calibration of a simulated LSL IMU (wall time)


class _LockedClock:
    """The simulated suit's clock, advancing the physics under the lock that the IMU peer's thread
    reads it under (:class:`~bowden.sim.peers.WallTimePlant`, never started: it only guards)."""

    def __init__(self, inner: Clock, plant: WallTimePlant) -> None:
        self._inner = inner
        self._plant = plant

    def now(self) -> float:
        return self._inner.now()

    def sleep_until(self, deadline_s: float) -> None:
        self._plant.call(lambda _: self._inner.sleep_until(deadline_s))


@dataclass(frozen=True, kw_only=True)
class SimulatedBackend:
    """Each trial on a fresh simulated suit worn by a virtual participant following the reference.

    The paper's AK60-6 is the simulator's own motor; another ``motor`` (or a ``firmware`` variant)
    is driven as ``bowden run --backend sim`` drives it: the real driver
    (:class:`~bowden.hardware.ak60.AK60Motor`, set up for that model's MIT-mode ranges) sends real
    frames to that model's simulated peer, which answers within the send
    (:mod:`bowden.sim.peers.inline_can`: the physics is paced, maybe faster than real time). With
    ``imu`` ``lsl:NAME`` the arm's orientation is published as an LSL quaternion stream of that name
    and read back by :class:`~bowden.hardware.lsl_imu.LslImuClient` after its arm-down calibration.

    Parameters
    ----------
    time_scale
        Simulated seconds per wall second (1 = real time, what a watching person needs).
    seed
        Seed of sensor and motor noise (each trial adds its number so trials differ).
    motor, firmware
        ``--motor`` and ``--firmware``: the TDU's AK model and firmware variant.
    imu
        ``--imu``: ``ngimu`` (the simulator's IMU) or ``lsl:STREAM_NAME``.
    """

    time_scale: float = 1.0
    seed: int = 0
    motor: str = DEFAULT_MOTOR
    firmware: str | None = None
    imu: str = "ngimu"
    name: str = BACKEND_SIM

    def __post_init__(self) -> None:  # refused when the server starts, not at every trial
        check_time_scale(self.time_scale)
        check_seed(self.seed)
        motor_model(self.motor).limits(self.firmware)
        if parse_imu(self.imu) is not None and self.time_scale > LSL_MAX_TIME_SCALE:
            raise ParameterError(f"--imu {self.imu} streams in wall time: --time-scale must be at most "
                                 f"{LSL_MAX_TIME_SCALE:g} with it, got {self.time_scale:g}")

    @property
    def devices(self) -> dict[str, str]:
        """What each trial's metadata records of the hardware (:func:`device_record`)."""
        from bowden.hardware.device_record import device_record

        return device_record(self.motor, self.firmware, self.imu)

    def open(self, setup: TrialSetup) -> OpenSuit:
        reference = setup.reference
        participant = VirtualParticipant(
            participant_id=setup.participant, subject=setup.subject, hand_load_kg=setup.hand_load_kg
        )
        expected = None
        if setup.support is not None:
            expected = ExpectedAssistance.for_condition(
                setup.support, setup.subject, hand_load_kg=setup.hand_load_kg
            )
        arm = ParticipantArm(
            participant,
            reference.cycle,
            cycles=reference.repetitions,
            start_s=reference.start_s,
            expected=expected,
        )
        suit = SimulatedSuit(arm=arm, seed=self.seed)
        warm_up_suit(PrescribedArm.following(reference.cycle))  # wired peers answer within ms, not a compile
        with ExitStack() as stack:
            plant = WallTimePlant(suit)
            clock = WallPacedClock(_LockedClock(suit.clock, plant), time_scale=self.time_scale)
            stack.callback(suit.motor.disable)
            motor: Motor = suit.motor
            if (self.motor, self.firmware) != (DEFAULT_MOTOR, None):
                motor = self._wired_motor(plant, clock, stack)
            elevation_sensor: ElevationSensor = suit.elevation_sensor
            stream = parse_imu(self.imu)
            if stream is not None:
                elevation_sensor = self._lsl_imu(plant, clock, stream, stack)
            limits = motor_model(self.motor).limits(self.firmware)
            devices = stack.pop_all()
        return OpenSuit(
            motor=motor,
            elevation_sensor=elevation_sensor,
            clock=clock,
            tension_sensor=suit.tension_sensor,
            description=f"simulated suit ({self.motor}, ±{limits.torque_nm:g} Nm; IMU {self.imu}), virtual "
                        f"participant, {self.time_scale:g}× real time",
            devices=self.devices,
            health=lambda: {"simulation_lag_ms": 1e3 * clock.worst_lag_s},
            close=devices.close,
        )

    def _wired_motor(self, plant: WallTimePlant, clock: WallPacedClock, stack: ExitStack) -> Motor:
        """The real driver, set up for ``motor``'s ranges, and that model's peer on an inline bus."""
        from bowden.hardware.ak60 import AK60Config, AK60Motor
        from bowden.sim.peers import AK60Peer
        from bowden.sim.peers.inline_can import inline_can_pair

        limits = motor_model(self.motor).limits(self.firmware)
        driver_bus, peer_bus = inline_can_pair(f"serve-{self.motor}")
        stack.callback(peer_bus.shutdown)
        stack.callback(driver_bus.shutdown)
        peer = AK60Peer(peer_bus, plant, limits=limits, time_source=clock.now).power_on()
        driver_bus.deliver = peer.answer
        # As bowden run (cli._suit.motor_config): another model is clamped at its torque field's range.
        config = AK60Config(limits=limits) if self.motor == DEFAULT_MOTOR else \
            AK60Config(limits=limits, torque_limit_nm=limits.torque_nm)
        # The driver's deadlines are wall time, as on a bus (the simulated clock stands still while
        # it waits); the loop judges replies on its own clock (runtime.motor_link), not the driver's.
        driver = AK60Motor(driver_bus, config)
        stack.callback(driver.__exit__, None, None, None)  # leaves motor mode if the loop did not
        return driver

    def _lsl_imu(self, plant: WallTimePlant, clock: WallPacedClock, stream: str,
                 stack: ExitStack) -> ElevationSensor:
        """The arm published as an LSL quaternion stream, read back by the LSL client (calibrated)."""
        from bowden.hardware.lsl_imu import LslImuClient, LslImuConfig
        from bowden.sim.peers.lsl_imu_peer import LslImuPeer

        peer = stack.enter_context(LslImuPeer(plant, stream, rate_hz=_LSL_SIM_RATE_HZ * self.time_scale))
        client = stack.enter_context(LslImuClient(LslImuConfig(stream_name=stream), clock=clock.now))
        peer.hold_arm_down()  # the participant stands with the arm hanging for the calibration
        peer.wait_until_sent()  # no state read before the pose reaches the calibration
        client.calibrate_arm_down(_CALIBRATION_S)
        peer.hold_arm_down(False)  # (the arm has no state to send until the trial advances it)
        return client
