"""``--imu lsl:NAME``: the LSL IMU client against a pylsl outlet in another process.

Discovery stays on this machine (``ResolveScope = machine`` via $LSLAPICFG, set for this module), and
each test's stream has a name of its own. The outlet (``lsl_imu_outlet.py``) computes its orientation
without bowden's code. In the real-time group of tests/conftest.py (LSL discovery is machine-wide).
"""

from __future__ import annotations

import itertools
import math
import os
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

pytest.importorskip("pylsl")

from bowden.errors import HardwareError, ParameterError
from bowden.hardware.lsl_imu import LslImuClient, LslImuConfig, parse_imu
from bowden.hardware.protocols import ElevationSample, ElevationSensor

HERE = Path(__file__).parent
_names = itertools.count()


@pytest.fixture(scope="module", autouse=True)
def machine_scope(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    config = tmp_path_factory.mktemp("lsl") / "lsl_api.cfg"
    config.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n")
    before = os.environ.get("LSLAPICFG")
    os.environ["LSLAPICFG"] = str(config)  # read by liblsl when it first starts, in this process too
    yield
    if before is None:
        os.environ.pop("LSLAPICFG", None)
    else:
        os.environ["LSLAPICFG"] = before


class Outlet:
    """The outlet process, steered on its stdin."""

    def __init__(self, kind: str) -> None:
        self.name = f"bowden-test-imu-{os.getpid()}-{next(_names)}"
        self.process = subprocess.Popen([sys.executable, str(HERE / "lsl_imu_outlet.py"), self.name, kind],
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert self.process.stdout is not None and self.process.stdout.readline().strip() == "ready"

    def say(self, command: str) -> None:
        assert self.process.stdin is not None and self.process.stdout is not None
        self.process.stdin.write(command + "\n")
        self.process.stdin.flush()
        assert self.process.stdout.readline().strip() == "ok"

    def close(self) -> None:
        try:
            self.say("quit")
            self.process.wait(timeout=10)
        finally:
            if self.process.poll() is None:
                self.process.kill()


@pytest.fixture
def outlet(request: pytest.FixtureRequest) -> Iterator[Outlet]:
    running = Outlet(getattr(request, "param", "quaternion"))
    yield running
    running.close()


def until(condition: Callable[[], ElevationSample | None], timeout_s: float = 10.0) -> ElevationSample:
    """Poll until ``condition`` returns a sample (a generous bound: only a broken client hangs)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        sample = condition()
        if sample is not None:
            return sample
        time.sleep(0.005)
    raise AssertionError("the condition never held")


def test_a_quaternion_stream_gives_the_elevation_after_the_arm_down_calibration(outlet: Outlet) -> None:
    with LslImuClient(LslImuConfig(stream_name=outlet.name)) as client:
        assert isinstance(client, ElevationSensor) and client.kind == "quaternion"
        assert client.read() is None  # no elevation before the calibration
        client.calibrate_arm_down(0.4)
        outlet.say("up 60")

        def raised() -> ElevationSample | None:
            sample = client.read()
            return sample if sample is not None and sample.elevation_rad > math.radians(59.0) else None
        sample = until(raised)
        assert sample.elevation_rad == pytest.approx(math.radians(60.0), abs=math.radians(0.01))
        assert sample.time_s <= time.monotonic()  # stamped on this host's clock when taken in
        time.sleep(0.1)
        held = client.read()
        assert held is not None and held.elevation_velocity_rad_s == pytest.approx(0.0, abs=0.05)


@pytest.mark.parametrize("outlet", ["elevation"], indirect=True)
def test_an_elevation_stream_in_degrees_needs_no_axis(outlet: Outlet) -> None:
    with LslImuClient(LslImuConfig(stream_name=outlet.name)) as client:
        assert client.kind == "elevation"
        assert client.calibrate_arm_down(0.3) is None
        outlet.say("up 45")

        def raised() -> ElevationSample | None:
            sample = client.read()
            return sample if sample is not None and sample.elevation_rad > 0.5 else None
        assert until(raised).elevation_rad == pytest.approx(math.radians(45.0), abs=1e-5)


def test_a_silent_stream_leaves_the_last_sample_to_age(outlet: Outlet) -> None:
    with LslImuClient(LslImuConfig(stream_name=outlet.name)) as client:
        client.calibrate_arm_down(0.3)
        until(client.read)
        outlet.say("silent")
        # What was already sent is taken in: until no sample has arrived for 0.1 s (a fixed pause
        # was not enough on a busy host, where LSL delivered the last samples later).
        deadline, taken, quiet_since = time.monotonic() + 10.0, -1, 0.0
        while time.monotonic() - quiet_since < 0.1:
            assert time.monotonic() < deadline, "samples kept arriving after the outlet went silent"
            client.read()
            if client.counters.samples != taken:
                taken, quiet_since = client.counters.samples, time.monotonic()
            time.sleep(0.01)
        last = client.read()
        time.sleep(0.2)
        assert client.read() is last  # nothing new: its age grows, and the loop's IMU watchdog stops the suit


def test_a_backlog_of_old_samples_is_stale_not_used(outlet: Outlet) -> None:
    with LslImuClient(LslImuConfig(stream_name=outlet.name, max_sample_age_s=0.1)) as client:
        client.calibrate_arm_down(0.3)
        fresh = until(client.read)
        outlet.say("up 60")
        outlet.say("stale 0.5")  # from now on every sample is half a second old when it arrives
        time.sleep(0.3)
        client.read()
        stale_before = client.counters.stale
        time.sleep(0.3)
        latest = client.read()
        assert client.counters.stale > stale_before
        assert latest is not None and latest.time_s < time.monotonic() - 0.25  # nothing fresh since
        assert latest.time_s >= fresh.time_s


def test_non_finite_orientations_reach_the_loop_as_such(outlet: Outlet) -> None:
    with LslImuClient(LslImuConfig(stream_name=outlet.name)) as client:
        client.calibrate_arm_down(0.3)
        outlet.say("nan")

        def broken() -> ElevationSample | None:
            sample = client.read()
            return sample if sample is not None and math.isnan(sample.elevation_rad) else None
        until(broken)
        assert client.counters.non_finite > 0


def test_a_missing_stream_names_what_is_visible(outlet: Outlet) -> None:
    client = LslImuClient(LslImuConfig(stream_name="no-such-imu", resolve_timeout_s=0.5))
    with pytest.raises(HardwareError, match=r"no LSL stream named 'no-such-imu'.*--imu lsl:no-such-imu.*"
                                            rf"visible: .*{outlet.name}"):
        client.start()


def test_the_imu_option_names_itself() -> None:
    assert parse_imu("ngimu") is None and parse_imu("lsl:Xsens DOT") == "Xsens DOT"
    with pytest.raises(ParameterError, match=r"--imu must be ngimu or lsl:STREAM_NAME, got 'lsl:'"):
        parse_imu("lsl:")


@pytest.mark.parametrize(("inject", "ok"), [([], True), (["--inject", "silent-imu"], False)])
def test_bowden_check_reads_an_lsl_imu(inject: list[str], ok: bool,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from bowden.cli import main

    name = f"bowden-test-check-{os.getpid()}-{next(_names)}"
    code = main(["check", "--backend", "sim", "--json", "--imu", f"lsl:{name}", "--calibration-s", "0.3",
                 "--imu-rate", "100", *inject])
    imu = next(item for item in json.loads(capsys.readouterr().out)["checks"] if item["name"] == "imu")
    assert (code == 0, imu["ok"]) == (ok, ok), imu
    if not ok:
        assert f"IMU calibration got 0 samples from the LSL stream '{name}'" in imu["message"]
