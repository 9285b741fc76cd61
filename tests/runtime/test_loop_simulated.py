"""The loop on the simulated suit's own clock: deterministic timing, exact watchdog and ramp times."""

from __future__ import annotations

import itertools
from types import TracebackType
from typing import Self

import pytest

from bowden.control import Controller, Fault
from bowden.errors import DeviceTimeoutError, ParameterError
from bowden.hardware.protocols import ElevationSample
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.runtime import ControlLoop, LoopConfig, LoopState, Row, SafetyConfig, ramp_torque_nm
from bowden.runtime.timing import LoopTiming
from bowden.sim.arm import PrescribedArm
from bowden.sim.suit import SimulatedSuit

RAMP_S = SafetyConfig().ramp_down_s
IMU_MAX_AGE_S = SafetyConfig().imu_max_age_s
assert (RAMP_S, IMU_MAX_AGE_S) == (0.03, 0.04)  # the defaults the counts below are written for


class FreezingImu:
    """The simulated IMU, which stops updating at ``freeze_at_s`` (a lost stream)."""

    def __init__(self, suit: SimulatedSuit, freeze_at_s: float) -> None:
        self.suit = suit
        self.freeze_at_s = freeze_at_s
        self.frozen: ElevationSample | None = None

    def read(self) -> ElevationSample | None:
        if self.suit.time_s < self.freeze_at_s:
            return self.suit.elevation_sensor.read()
        if self.frozen is None:
            self.frozen = self.suit.elevation_sensor.read()
        return self.frozen

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        return None


def make_suit() -> SimulatedSuit:
    return SimulatedSuit(arm=PrescribedArm.following(MinimumJerkCycle()))


def test_simulated_trial_runs_on_the_suit_clock(controller: Controller) -> None:
    suit = make_suit()
    rows: list[Row] = []
    cycle = MinimumJerkCycle()
    loop = ControlLoop(
        controller=controller, motor=suit.motor, elevation_sensor=suit.elevation_sensor, clock=suit.clock,
        config=LoopConfig(rate_hz=500.0, duration_s=2.0), tension_sensor=suit.tension_sensor,
        record=rows.append, reference_elevation=lambda t: float(cycle.elevation_rad(t)),
    )
    report = loop.run()
    assert report.clean and report.fault == Fault.NONE
    # Simulated time: every cycle exactly on its deadline, nothing missed.
    assert report.timing.deadline_misses == 0 and report.timing.worst_lateness_s == 0.0
    times = [row[0] for row in rows]
    assert all(b - a == pytest.approx(0.002, abs=1e-12) for a, b in itertools.pairwise(times))
    # 2 s of assistance, then the 30 ms ramp (15 cycles at 500 Hz) ending on a zero command.
    running = [row for row in rows if row[10] == LoopState.RUNNING]
    ramp = [row for row in rows if row[10] == LoopState.RAMPING_DOWN]
    assert len(running) == 1000  # t = 0 … 1.998 s; the cycle at 2.0 s starts the ramp
    assert report.zero_torque_time_s - report.stop_time_s == pytest.approx(RAMP_S, abs=1e-9)
    assert ramp[-1][6] == 0.0 and len(ramp) == 16
    assert not suit.motor.enabled
    # The suit carried the arm: the measured tension followed the desired one on average.
    desired = [row[4] for row in running[250:]]
    measured = [row[9] for row in running[250:]]
    assert sum(measured) / len(measured) == pytest.approx(sum(desired) / len(desired), rel=0.35)


def test_stale_imu_detected_on_the_exact_cycle(controller: Controller) -> None:
    suit = make_suit()
    imu = FreezingImu(suit, freeze_at_s=0.5)
    rows: list[Row] = []
    suit_times: list[float] = []

    def record(row: Row) -> None:
        rows.append(row)
        suit_times.append(suit.time_s)

    loop = ControlLoop(
        controller=controller, motor=suit.motor, elevation_sensor=imu, clock=suit.clock,
        config=LoopConfig(rate_hz=1000.0, duration_s=2.0), record=record,
    )
    report = loop.run()
    assert report.fault == Fault.IMU_STALE
    frozen = imu.frozen
    assert frozen is not None
    # The stop is the first cycle at which the newest sample is more than 40 ms old, not one later.
    first_stale = next(i for i, now in enumerate(suit_times) if now - frozen.time_s > IMU_MAX_AGE_S)
    assert rows[first_stale][0] == report.stop_time_s
    assert rows[first_stale][10] == LoopState.RAMPING_DOWN
    assert rows[first_stale - 1][10] == LoopState.RUNNING
    assert report.zero_torque_time_s - report.stop_time_s == pytest.approx(RAMP_S, abs=1e-9)
    ramp = [row for row in rows if row[10] == LoopState.RAMPING_DOWN]
    for row in ramp:
        expected_torque = ramp_torque_nm(ramp[0][6], row[0] - report.stop_time_s, RAMP_S)
        assert row[6] == pytest.approx(expected_torque, abs=1e-12)
    assert not suit.motor.enabled


def test_refuses_to_start_without_imu(controller: Controller) -> None:
    suit = make_suit()

    class SilentImu(FreezingImu):
        def read(self) -> ElevationSample | None:
            return None

    loop = ControlLoop(controller=controller, motor=suit.motor, elevation_sensor=SilentImu(suit, 0.0),
                       clock=suit.clock, config=LoopConfig(safety=SafetyConfig(imu_startup_timeout_s=0.1)))
    with pytest.raises(DeviceTimeoutError, match="no elevation sample"):
        loop.run()
    assert not suit.motor.enabled  # never enabled


def test_unexpected_error_still_leaves_motor_mode(controller: Controller) -> None:
    suit = make_suit()

    def broken_record(row: Row) -> None:
        if row[0] > 0.1:
            raise RuntimeError("recorder bug")

    loop = ControlLoop(controller=controller, motor=suit.motor, elevation_sensor=suit.elevation_sensor,
                       clock=suit.clock, config=LoopConfig(duration_s=1.0), record=broken_record)
    with pytest.raises(RuntimeError, match="recorder bug"):
        loop.run()
    assert not suit.motor.enabled


def test_ramp_shape() -> None:
    assert ramp_torque_nm(2.0, 0.0, 0.05) == 2.0
    assert ramp_torque_nm(2.0, 0.025, 0.05) == pytest.approx(1.0)
    assert ramp_torque_nm(2.0, 0.05, 0.05) == 0.0
    assert ramp_torque_nm(2.0, 1.0, 0.05) == 0.0


def test_timing_accounting_by_hand() -> None:
    timing = LoopTiming(1000.0)
    for lateness in [0.0] * 97 + [0.000_05, 0.000_2, 0.003]:
        timing.record(lateness, finished_late=lateness > 0.001)
    timing.skip(2)
    summary = timing.summary()
    assert summary.cycles == 100 and summary.skipped_cycles == 2
    assert summary.deadline_misses == 3  # one overrun and two skipped
    assert summary.miss_fraction == pytest.approx(3 / 102)
    assert summary.worst_lateness_s == 0.003
    assert summary.p50_lateness_s == pytest.approx(1e-5)  # upper edge of the first 10 µs bin
    assert summary.p99_lateness_s == pytest.approx(0.000_21)
    assert "3 deadline misses" in summary.describe()


def test_config_validation() -> None:
    with pytest.raises(ParameterError, match="ramp_down_s"):
        SafetyConfig(ramp_down_s=0.2)
    with pytest.raises(ParameterError, match="imu_max_age_s"):
        SafetyConfig(imu_max_age_s=0.0)
    with pytest.raises(ParameterError, match="rate_hz"):
        LoopConfig(rate_hz=5000.0)
    with pytest.raises(ParameterError, match="duration_s"):
        LoopConfig(duration_s=-1.0)


class StallingClock:
    """The suit's clock, but the loop wakes ``stall_s`` late once, at the first deadline ≥ ``at_s``
    (the process was not scheduled: the suit's physics and sensors went on meanwhile)."""

    def __init__(self, suit: SimulatedSuit, at_s: float, stall_s: float) -> None:
        self.suit = suit
        self.at_s = at_s
        self.stall_s = stall_s
        self.stalled = False

    def now(self) -> float:
        return self.suit.time_s

    def sleep_until(self, deadline_s: float) -> None:
        if not self.stalled and deadline_s >= self.at_s:
            self.stalled = True
            deadline_s += self.stall_s
        self.suit.advance_to(deadline_s)


class MotorFallingSilent:
    """The suit's motor, whose replies stop arriving from ``silent_at_s`` on (it still acts)."""

    def __init__(self, suit: SimulatedSuit, silent_at_s: float) -> None:
        self.suit = suit
        self.silent_at_s = silent_at_s
        self.first_silent_send_s: float | None = None

    def __getattr__(self, name: str) -> object:
        return getattr(self.suit.motor, name)

    def command_torque(self, torque_nm: float) -> object:
        state = self.suit.motor.command_torque(torque_nm)
        if self.suit.time_s < self.silent_at_s:
            return state
        if self.first_silent_send_s is None:
            self.first_silent_send_s = self.suit.time_s
        return None


def test_motor_silence_is_judged_on_commands_sent(controller: Controller) -> None:
    suit = make_suit()
    motor = MotorFallingSilent(suit, silent_at_s=0.5)
    starts: list[float] = []  # suit time of loop time 0

    def record(row: Row) -> None:
        if not starts:
            starts.append(suit.time_s - row[0])

    loop = ControlLoop(controller=controller, motor=motor,  # type: ignore[arg-type]
                       elevation_sensor=suit.elevation_sensor, clock=suit.clock,
                       config=LoopConfig(rate_hz=500.0, duration_s=2.0), record=record)
    report = loop.run()
    assert report.fault == Fault.MOTOR_NO_REPLY
    safety = SafetyConfig()
    assert motor.first_silent_send_s is not None
    # The reply to the last command before the silence was still expected: its send (one period
    # before the first unanswered poll) is the oldest unanswered one. The stop is the first cycle
    # more than 30 ms after it, with at least 5 commands unanswered.
    oldest = motor.first_silent_send_s - 0.002
    age = starts[0] + report.stop_time_s - oldest
    assert safety.motor_max_silence_s < age <= safety.motor_max_silence_s + 0.002 + 1e-9
    unanswered = round(age / 0.002)
    assert unanswered >= safety.motor_min_unanswered
    assert f"no valid reply to the last {unanswered} commands" in report.reason


@pytest.mark.parametrize("stall_s", [0.04, 0.09])
def test_a_tolerated_host_stall_is_counted_not_a_fault(controller: Controller, stall_s: float) -> None:
    suit = make_suit()
    events: list[tuple[float, str, str]] = []
    loop = ControlLoop(controller=controller, motor=suit.motor, elevation_sensor=suit.elevation_sensor,
                       clock=StallingClock(suit, 0.7, stall_s), config=LoopConfig(duration_s=1.5),
                       tension_sensor=suit.tension_sensor,
                       on_event=lambda t, kind, message: events.append((t, kind, message)))
    report = loop.run()
    assert report.clean and report.fault == Fault.NONE, report.reason
    assert report.host_stalls == 1
    assert report.worst_host_stall_s == pytest.approx(stall_s, abs=1e-9)
    assert [kind for _, kind, _ in events] == ["host_stall"]
    assert f"not scheduled for {1e3 * stall_s:.0f} ms" in events[0][2]
    assert "host stalls 1" in report.describe_health()


def stall_end_time(rows: list[Row]) -> float:
    """Loop time of the first cycle after the stall (the one gap longer than a period)."""
    return next(b[0] for a, b in itertools.pairwise(rows) if b[0] - a[0] > 0.0021)


def test_a_host_stall_beyond_the_bound_stops_with_its_reason(controller: Controller) -> None:
    suit = make_suit()
    rows: list[Row] = []
    loop = ControlLoop(controller=controller, motor=suit.motor, elevation_sensor=suit.elevation_sensor,
                       clock=StallingClock(suit, 0.7, 0.15), config=LoopConfig(duration_s=1.5),
                       record=rows.append)
    report = loop.run()
    assert report.fault == Fault.HOST_STALL
    assert report.reason == "host stall: the loop was not scheduled for 150 ms (limit 100 ms)"
    assert report.stop_time_s == stall_end_time(rows)  # the first cycle after the stall stops
    assert not suit.motor.enabled


def test_sample_ages_count_from_the_end_of_a_stall(controller: Controller) -> None:
    """A sensor whose thread stalled with the loop is not stale because of the stall alone."""
    suit = make_suit()
    imu = FreezingImu(suit, freeze_at_s=0.69)  # its newest sample is from before the stall
    rows: list[Row] = []
    loop = ControlLoop(controller=controller, motor=suit.motor, elevation_sensor=imu,
                       clock=StallingClock(suit, 0.7, 0.09), config=LoopConfig(rate_hz=500.0, duration_s=1.5),
                       record=rows.append)
    report = loop.run()
    assert report.fault == Fault.IMU_STALE
    # 100 ms old when the stall ended, yet counted from the end of the stall: stale 40 ms later
    # (the cycle on the limit or the next, as rounding of the clock's sum falls).
    end = stall_end_time(rows)
    assert end + IMU_MAX_AGE_S - 1e-9 <= report.stop_time_s <= end + IMU_MAX_AGE_S + 0.002 + 1e-9
