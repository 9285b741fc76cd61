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
    # 2 s of assistance, then the 50 ms ramp (25 cycles at 500 Hz) ending on a zero command.
    running = [row for row in rows if row[10] == LoopState.RUNNING]
    ramp = [row for row in rows if row[10] == LoopState.RAMPING_DOWN]
    assert len(running) == 1000  # t = 0 … 1.998 s; the cycle at 2.0 s starts the ramp
    assert report.zero_torque_time_s - report.stop_time_s == pytest.approx(0.05, abs=1e-9)
    assert ramp[-1][6] == 0.0 and len(ramp) == 26
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
    # The stop is the first cycle at which the newest sample is more than 50 ms old, not one later.
    first_stale = next(i for i, now in enumerate(suit_times) if now - frozen.time_s > 0.05)
    assert rows[first_stale][0] == report.stop_time_s
    assert rows[first_stale][10] == LoopState.RAMPING_DOWN
    assert rows[first_stale - 1][10] == LoopState.RUNNING
    assert report.zero_torque_time_s - report.stop_time_s == pytest.approx(0.05, abs=1e-9)
    ramp = [row for row in rows if row[10] == LoopState.RAMPING_DOWN]
    for row in ramp:
        expected_torque = ramp_torque_nm(ramp[0][6], row[0] - report.stop_time_s, 0.05)
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
