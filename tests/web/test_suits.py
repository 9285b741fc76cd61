import math
from pathlib import Path

import pytest

from bowden.cli import main
from bowden.errors import ParameterError
from bowden.hardware.protocols import Clock, ElevationSensor, Motor
from bowden.web.suits import SimulatedBackend, WallPacedClock
from bowden.web.trial_setup import parse_setup

from .conftest import trial_request


class SteppedClock:
    """A simulated clock that jumps to each deadline (like SimulatedSuit.clock)."""

    def __init__(self) -> None:
        self.time_s = 0.0

    def now(self) -> float:
        return self.time_s

    def sleep_until(self, deadline_s: float) -> None:
        self.time_s = max(self.time_s, deadline_s)


class FakeWall:
    def __init__(self) -> None:
        self.time_s = 100.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.time_s

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.time_s += seconds


def test_simulated_time_is_paced_to_the_wall_clock():
    wall = FakeWall()
    clock = WallPacedClock(SteppedClock(), time_scale=2.0, wall=wall, sleep=wall.sleep)
    for k in range(1, 6):
        clock.sleep_until(0.1 * k)
        assert clock.now() == pytest.approx(0.1 * k)
        assert wall.time_s == pytest.approx(100.0 + 0.05 * k)  # half as much wall time at 2x
    assert clock.worst_lag_s == 0.0


def test_a_simulation_that_falls_behind_reports_its_lag():
    wall = FakeWall()
    clock = WallPacedClock(SteppedClock(), wall=wall, sleep=wall.sleep)
    clock.sleep_until(0.01)
    wall.time_s += 0.5  # a stall of half a second
    clock.sleep_until(0.02)
    assert clock.worst_lag_s == pytest.approx(0.49)
    assert len(wall.sleeps) == 1  # no sleep when already late


def test_time_scale_is_validated():
    with pytest.raises(ParameterError, match="time_scale"):
        WallPacedClock(SteppedClock(), time_scale=0.0)
    with pytest.raises(ParameterError, match="time_scale"):
        WallPacedClock(SteppedClock(), time_scale=math.inf)


def test_the_simulated_backend_gives_hardware_protocol_devices():
    suit = SimulatedBackend().open(parse_setup(trial_request(condition="no_suit")))
    assert isinstance(suit.motor, Motor)
    assert isinstance(suit.elevation_sensor, ElevationSensor)
    assert isinstance(suit.clock, Clock)
    suit.clock.sleep_until(0.05)
    sample = suit.elevation_sensor.read()
    assert sample is not None and math.degrees(sample.elevation_rad) == pytest.approx(20.0, abs=3.0)
    suit.close()


def test_a_context_backend_opens_per_trial_and_closes_after(tmp_path):
    from contextlib import contextmanager

    from bowden.sim.suit import SimulatedSuit
    from bowden.web.suits import ContextBackend, OpenSuit

    events = []

    @contextmanager
    def open_suit(setup):
        events.append(("open", setup.participant))
        suit = SimulatedSuit()
        try:
            yield OpenSuit(motor=suit.motor, elevation_sensor=suit.elevation_sensor, clock=suit.clock,
                           description="wrapped")
        finally:
            events.append(("closed", suit.motor.enabled))

    backend = ContextBackend("wrapped", open_suit)
    opened = backend.open(parse_setup(trial_request(participant="P31")))
    opened.motor.enable()
    assert backend.name == "wrapped" and events == [("open", "P31")]
    opened.motor.disable()
    opened.close()
    assert events == [("open", "P31"), ("closed", False)]


@pytest.mark.parametrize("time_scale", [math.nan, 0.0, -1.0, 1e9])
def test_a_simulated_backend_with_an_unusable_time_scale_is_refused_at_startup(
    time_scale: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(ParameterError, match="time_scale must be in"):
        SimulatedBackend(time_scale=time_scale)
    store = tmp_path / "s.sqlite"
    assert main(["serve", "--time-scale", repr(time_scale), "--store", str(store)]) == 1
    assert "bowden: error: --time-scale must be in" in capsys.readouterr().err  # the flag, not the field
    assert not store.exists()
