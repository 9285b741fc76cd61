"""The bench's safe stop ramps both torques to zero over ``ramp_down_s`` of the clock, then sends
both exit frames before it waits for either reply."""

from __future__ import annotations

import itertools

import pytest

from bowden.runtime.bench_config import BenchDevices
from bowden.runtime.bench_safe_stop import safe_stop


class Clock:
    """A clock that each motor command costs ``command_s`` of (a loaded host)."""

    def __init__(self, command_s: float) -> None:
        self.time_s = 100.0
        self.command_s = command_s

    def now(self) -> float:
        return self.time_s

    def sleep_until(self, deadline_s: float) -> None:
        self.time_s = max(self.time_s, deadline_s)


class Motor:
    """Records what it was told, when; ``answers`` False: a silent motor."""

    def __init__(self, clock: Clock, answers: bool = True) -> None:
        self.clock, self.answers = clock, answers
        self.torques: list[tuple[float, float]] = []
        self.exits: list[float] = []

    def command_torque(self, torque_nm: float) -> None:
        self.clock.time_s += self.clock.command_s
        self.torques.append((self.clock.time_s, torque_nm))

    def request_exit(self) -> None:
        self.exits.append(self.clock.time_s)

    def await_exit(self) -> bool:
        if not self.answers:
            self.clock.time_s += 0.1  # AK60Config.special_reply_timeout_s
        return self.answers


def stop(command_s: float, mannequin_answers: bool = True) -> tuple[Motor, Motor, float]:
    clock = Clock(command_s)
    tdu, mannequin = Motor(clock), Motor(clock, answers=mannequin_answers)
    devices = BenchDevices(tdu=tdu, mannequin=mannequin, imu=None, load_cell=None, clock=clock)  # type: ignore[arg-type]
    errors: list[str] = []
    end = safe_stop(devices, period_s=0.001, ramp_down_s=0.03, tdu_torque_nm=2.0, mannequin_torque_nm=3.0,
                    errors=errors)
    assert errors == []
    return tdu, mannequin, end


def test_on_time_the_ramp_steps_down_once_a_cycle_to_zero() -> None:
    tdu, mannequin, _ = stop(command_s=0.0)
    steps = [round(2.0 * (1 - k / 30), 9) for k in range(1, 31)]
    assert [round(torque, 9) for _, torque in tdu.torques] == steps
    assert mannequin.torques[-1][1] == 0.0 and len(mannequin.torques) == 30
    assert tdu.exits == mannequin.exits == [pytest.approx(100.03, abs=0.0011)]


def test_a_late_loop_still_ramps_over_the_ramp_s_time_and_exits_on_time() -> None:
    # Each command 2 ms (a cycle 4 ms against its 1 ms): the ramp ends by the clock, in ~30 ms.
    tdu, mannequin, _ = stop(command_s=0.002)
    assert tdu.torques[-1][1] == mannequin.torques[-1][1] == 0.0
    torques = [torque for _, torque in tdu.torques]
    assert all(later <= earlier for earlier, later in itertools.pairwise(torques))
    # The ramp, then at most the cycle under way and the one that commands zero (counted in cycles,
    # 30 of them: 120 ms).
    assert tdu.exits[0] - 100.0 <= 0.03 + 2 * 0.004
    assert len(tdu.torques) <= 10


def test_a_silent_motor_does_not_delay_the_other_s_exit() -> None:
    tdu, mannequin, end = stop(command_s=0.0, mannequin_answers=False)
    # Both sent before any reply was waited for.
    assert tdu.exits[0] == mannequin.exits[0] == pytest.approx(100.03, abs=0.0011)
    assert len(mannequin.exits) == 2 and end > 100.2  # the silent one asked twice, 100 ms each
