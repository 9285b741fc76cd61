"""How the NGIMU client takes datagrams in: only from the IMU, bounded per read, stamped on take-in.

Real UDP on loopback between sockets: the simulated NGIMU (:class:`~bowden.sim.peers.NgimuPeer`) or a
plain socket standing for the IMU, and other sockets sending well-formed NGIMU bundles (spoofers),
floods and garbage. No verdict depends on how fast anything runs: samples are waited for by polling
``read()``, and the stamps come from an injected clock.
"""

from __future__ import annotations

import logging
import math
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

import pytest
from pythonosc.osc_bundle_builder import OscBundleBuilder
from pythonosc.osc_message_builder import OscMessageBuilder

from bowden.errors import DeviceTimeoutError, ParameterError
from bowden.hardware.elevation import ArmDownCalibration
from bowden.hardware.ngimu import NgimuClient, NgimuConfig, parse_sender
from bowden.hardware.protocols import ElevationSample
from bowden.sim.peers import NgimuPeer, WallTimePlant
from bowden.sim.peers.ngimu_peer import DEFAULT_MOUNTING, arm_orientation

if TYPE_CHECKING:
    from conftest import SimplePlant

HEADING_RAD = 0.4  # NgimuPeer's default plane of elevation
ARM_DOWN = ArmDownCalibration.from_quaternions([arm_orientation(0.0, HEADING_RAD, DEFAULT_MOUNTING)])


class FixedArm:
    """An arm held at one elevation (what the simulated plant reports to the peer)."""

    def __init__(self, elevation_rad: float) -> None:
        self.elevation_rad = elevation_rad

    def read(self) -> ElevationSample:
        return ElevationSample(0.0, self.elevation_rad, 0.0)


def wait_for(condition: Callable[[], bool], timeout_s: float = 10.0) -> None:
    """Poll ``condition`` until it holds; fail with a clear message after a generous timeout."""
    end = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > end:
            raise AssertionError("condition not met within the timeout")
        time.sleep(0.002)


def arm_bundle(elevation_deg: float) -> bytes:
    """A well-formed NGIMU ``/quaternion`` bundle for the arm at ``elevation_deg``."""
    builder = OscMessageBuilder(address="/quaternion")
    for value in arm_orientation(math.radians(elevation_deg), HEADING_RAD, DEFAULT_MOUNTING):
        builder.add_arg(float(value), OscMessageBuilder.ARG_TYPE_FLOAT)
    bundle = OscBundleBuilder(time.time())  # type: ignore[arg-type]  # python-osc takes float seconds
    bundle.add_content(builder.build())
    return bytes(bundle.build().dgram)


def elevation_deg(sample: ElevationSample | None) -> float:
    assert sample is not None
    return math.degrees(sample.elevation_rad)


@pytest.fixture
def udp() -> Iterator[Callable[[], socket.socket]]:
    """Make loopback UDP sockets (bound to a free port), closed after the test."""
    made: list[socket.socket] = []

    def make() -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind(("127.0.0.1", 0))
        made.append(sock)
        return sock

    yield make
    for sock in made:
        sock.close()


@pytest.fixture
def arm(plant: SimplePlant) -> FixedArm:
    fixed = FixedArm(math.radians(70.0))
    plant.elevation_sensor = fixed  # type: ignore[assignment]
    return fixed


def source_of(sock: socket.socket) -> tuple[str, int]:
    host, port = sock.getsockname()[:2]
    return str(host), int(port)


# --- accept only our IMU -------------------------------------------------------------------------
def test_a_spoofer_sending_from_the_start_is_never_used(wall_plant: WallTimePlant, arm: FixedArm,
                                                        udp: Callable[[], socket.socket],
                                                        caplog: pytest.LogCaptureFixture) -> None:
    # The spoofer sends the arm at 100° throughout: while the client locks in (its first take-in,
    # inside the calibration), during the calibration and during the run. The arm is at 70°.
    caplog.set_level(logging.INFO, logger="bowden.hardware.ngimu")
    spoofer = udp()
    stop = threading.Event()
    spoofed = [0]
    with NgimuClient(NgimuConfig(port=0)) as client, \
            NgimuPeer(wall_plant, client.address, rate_hz=400.0) as peer:
        peer.hold_arm_down()
        # A bundle of the arm at 70° read just before the flag (a preempted peer thread on a busy
        # host) is then on the socket before the calibration, not inside it.
        peer.wait_until_sent()  # the peer's bundles wait on the socket, nothing read yet

        def spoof() -> None:
            while not stop.is_set():
                spoofer.sendto(arm_bundle(100.0), client.address)
                spoofed[0] += 1
                stop.wait(0.001)

        thread = threading.Thread(target=spoof, name="spoofer")
        thread.start()
        try:
            wait_for(lambda: spoofed[0] >= 1)
            calibration = client.calibrate_arm_down(0.1, min_samples=5)
            peer.hold_arm_down(False)
            # The same after it: the arm-down bundles read before the flag cleared are all sent now,
            # taken in here, and the samples judged below are the ones taken in after them.
            peer.wait_until_sent()
            assert client.poll() < client.config.max_datagrams_per_read
            arm_down = client.read()
            # Every orientation collected was the peer's arm hanging down: the axis is the mounting's.
            assert all(abs(a - b) < 1e-6 for a, b in zip(calibration.axis, ARM_DOWN.axis, strict=True))
            assert client.counters.foreign >= 1
            foreign_before = client.counters.foreign
            samples: list[ElevationSample] = []

            def gathered() -> bool:
                sample = client.read()
                last = samples[-1] if samples else arm_down
                if sample is not None and (last is None or sample.time_s > last.time_s):
                    samples.append(sample)
                return len(samples) >= 50 and client.counters.foreign >= foreign_before + 50

            wait_for(gathered)
        finally:
            stop.set()
            thread.join()
        assert all(abs(elevation_deg(s) - 70.0) < 1e-3 for s in samples)
        assert client.sender is not None and client.sender[1] != source_of(spoofer)[1]
        assert client.counters.foreign <= spoofed[0]
    locked = [r for r in caplog.records if "accepting only" in r.getMessage()]
    assert len(locked) == 1 and locked[0].levelno == logging.INFO
    ignored = [r for r in caplog.records if "ignoring datagrams" in r.getMessage()]
    assert len(ignored) == 1 and ignored[0].levelno == logging.WARNING  # once per source, not per datagram


def test_the_first_osc_source_is_locked_in_even_within_one_read(udp: Callable[[], socket.socket]) -> None:
    imu, spoofer = udp(), udp()
    with NgimuClient(NgimuConfig(port=0), calibration=ARM_DOWN) as client:
        spoofer.sendto(b"\x00\x01not osc", client.address)  # not OSC: cannot claim the lock
        imu.sendto(arm_bundle(45.0), client.address)
        for _ in range(3):
            spoofer.sendto(arm_bundle(100.0), client.address)  # in the same read, after the lock
        wait_for(lambda: client.read() is not None and client.counters.foreign == 3)
        assert elevation_deg(client.read()) == pytest.approx(45.0, abs=1e-3)
        assert client.sender == source_of(imu)
        assert client.counters.malformed == 1 and client.counters.quaternions == 1


def test_a_configured_sender_drops_the_peer_when_it_sends_from_elsewhere(
        wall_plant: WallTimePlant, arm: FixedArm, udp: Callable[[], socket.socket]) -> None:
    imu = udp()
    config = NgimuConfig(port=0, sender=source_of(imu))  # (IP, port): the peer's socket is not it
    with NgimuClient(config, calibration=ARM_DOWN) as client, \
            NgimuPeer(wall_plant, client.address, rate_hz=400.0) as peer:
        wait_for(lambda: peer.sent >= 5)
        wait_for(lambda: client.read() is None and client.counters.foreign >= 10)
        assert client.counters.quaternions == 0 and client.counters.datagrams == 0
        with pytest.raises(DeviceTimeoutError, match=f"from 127.0.0.1:{source_of(imu)[1]}"):
            client.calibrate_arm_down(0.02, min_samples=1)
        imu.sendto(arm_bundle(45.0), client.address)
        wait_for(lambda: client.read() is not None)
        assert elevation_deg(client.read()) == pytest.approx(45.0, abs=1e-3)
        assert client.sender == source_of(imu)


def test_garbage_from_the_locked_sender_is_counted_and_the_stream_goes_on(
        udp: Callable[[], socket.socket]) -> None:
    imu = udp()
    garbage = (b"\x00\x01garbage", b"#bundle\x00\xff", b"/x\x00\x00,s\x00\x00", b"\xff" * 7, b"")
    with NgimuClient(NgimuConfig(port=0), calibration=ARM_DOWN) as client:
        imu.sendto(arm_bundle(45.0), client.address)
        wait_for(lambda: client.read() is not None)
        assert client.sender == source_of(imu)
        for payload in garbage:
            imu.sendto(payload, client.address)
        imu.sendto(arm_bundle(50.0), client.address)
        wait_for(lambda: client.read() is not None and client.counters.quaternions == 2)
        assert elevation_deg(client.read()) == pytest.approx(50.0, abs=1e-3)
        assert client.counters.malformed == len(garbage)
        assert client.counters.foreign == 0 and client.sender == source_of(imu)


def test_foreign_senders_are_logged_a_bounded_number_of_times(caplog: pytest.LogCaptureFixture) -> None:
    client = NgimuClient(NgimuConfig(sender="10.0.0.7"), calibration=ARM_DOWN)
    for port in range(1000, 1100):
        for _ in range(3):
            client.handle_datagram(arm_bundle(100.0), sender=("10.0.0.8", port))
    client.handle_datagram(arm_bundle(30.0), sender=("::ffff:10.0.0.7", 5555))  # IPv4-mapped: the IMU
    assert client.counters.foreign == 300
    warnings = [r for r in caplog.records if r.levelno == logging.WARNING]
    assert 1 <= len(warnings) <= 40
    assert elevation_deg(client.read()) == pytest.approx(30.0, abs=1e-3)


# --- bounded take-in -------------------------------------------------------------------------------
def test_a_flood_never_makes_one_read_take_more_than_the_bound(udp: Callable[[], socket.socket]) -> None:
    bound, newest = 64, 4
    clock_calls = [0]

    def clock() -> float:
        clock_calls[0] += 1
        return 1.0

    imu = udp()
    config = NgimuConfig(port=0, max_datagrams_per_read=bound, parse_newest=newest)
    with NgimuClient(config, calibration=ARM_DOWN, clock=clock) as client:
        imu.sendto(arm_bundle(45.0), client.address)
        wait_for(lambda: client.read() is not None)  # the IMU is locked in
        taken_total = 0
        for _ in range(20):  # 10 000 datagrams from the IMU's own address, in bursts of 500
            for _ in range(500):
                imu.sendto(arm_bundle(45.0), client.address)
            quaternions, calls = client.counters.quaternions, clock_calls[0]
            taken = client.poll()
            assert taken <= bound
            assert client.counters.quaternions - quaternions <= newest
            assert clock_calls[0] - calls <= newest
            taken_total += taken
        while (taken := client.poll()) > 0:  # the rest waited on the socket; each read stays bounded
            assert taken <= bound
            taken_total += taken
        c = client.counters
        assert c.read_limit_hits >= 20  # the socket held more than the bound after every burst
        assert taken_total <= 10_000  # the kernel dropped what did not fit in its buffer
        assert c.datagrams == 1 + taken_total and c.datagrams == c.quaternions + c.skipped_backlog
        imu.sendto(arm_bundle(60.0), client.address)  # the stream goes on after the flood
        wait_for(lambda: abs(elevation_deg(client.read()) - 60.0) < 1e-3)


def test_a_foreign_flood_does_not_push_the_imu_out_of_a_read(udp: Callable[[], socket.socket]) -> None:
    # Only the IMU's newest datagrams are parsed, but the foreign ones are dropped first: the IMU's
    # bundle, older than 100 foreign datagrams of the same read, is still used.
    imu, flooder = udp(), udp()
    config = NgimuConfig(port=0, sender=source_of(imu), parse_newest=4)
    with NgimuClient(config, calibration=ARM_DOWN) as client:
        imu.sendto(arm_bundle(45.0), client.address)
        for _ in range(100):
            flooder.sendto(arm_bundle(100.0), client.address)
        wait_for(lambda: client.read() is not None and client.counters.foreign == 100)
        assert elevation_deg(client.read()) == pytest.approx(45.0, abs=1e-3)
        assert client.counters.skipped_backlog == 0


# --- stamped when taken in -----------------------------------------------------------------------
def test_a_sample_is_stamped_with_the_client_clock_when_read_takes_it_in(
        udp: Callable[[], socket.socket]) -> None:
    now = [10.0]
    imu = udp()
    with NgimuClient(NgimuConfig(port=0), calibration=ARM_DOWN, clock=lambda: now[0]) as client:
        imu.sendto(arm_bundle(45.0), client.address)  # sent at 10.0 ...
        now[0] = 12.5  # ... while the host stalls: nobody takes it in until 12.5
        wait_for(lambda: client.read() is not None)
        sample = client.read()
        assert sample is not None and sample.time_s == 12.5
        now[0] = 13.0
        assert client.read() == sample  # nothing new: the same sample, not restamped
        imu.sendto(arm_bundle(50.0), client.address)
        wait_for(lambda: (s := client.read()) is not None and s.time_s == 13.0)
        assert elevation_deg(client.read()) == pytest.approx(50.0, abs=1e-3)


# --- no thread, never blocking ---------------------------------------------------------------------
def test_the_client_runs_no_thread(udp: Callable[[], socket.socket]) -> None:
    before = set(threading.enumerate())
    imu = udp()
    with NgimuClient(NgimuConfig(port=0), calibration=ARM_DOWN) as client:
        assert set(threading.enumerate()) == before
        imu.sendto(arm_bundle(45.0), client.address)
        wait_for(lambda: client.read() is not None)
        with pytest.raises(DeviceTimeoutError):
            client.calibrate_arm_down(0.01, min_samples=1000)
        assert set(threading.enumerate()) == before
    assert set(threading.enumerate()) == before
    assert client.read() is not None  # closed: the last sample stays, nothing is taken in


def test_read_does_not_wait_while_another_thread_takes_datagrams_in(udp: Callable[[], socket.socket]) -> None:
    imu = udp()
    with NgimuClient(NgimuConfig(port=0), calibration=ARM_DOWN) as client:
        imu.sendto(arm_bundle(45.0), client.address)
        with client._lock:  # as if a console or a calibration were taking datagrams in right now
            assert client.read() is None  # returns at once (a blocking read would deadlock here)
            assert client.poll() == 0
        wait_for(lambda: client.read() is not None)


def test_calibration_arguments_and_state_are_checked() -> None:
    client = NgimuClient(NgimuConfig(port=0))
    with pytest.raises(ParameterError, match="not started"):
        client.calibrate_arm_down(0.01)
    with client:
        with pytest.raises(ParameterError, match="duration_s"):
            client.calibrate_arm_down(0.0)
        with pytest.raises(ParameterError, match="min_samples"):
            client.calibrate_arm_down(0.01, min_samples=0)


# --- configuration ---------------------------------------------------------------------------------
@pytest.mark.parametrize(("given", "accepted"), [
    ("10.0.0.7", ("10.0.0.7", None)),
    ("10.0.0.7:8001", ("10.0.0.7", 8001)),
    (("10.0.0.7", 8001), ("10.0.0.7", 8001)),
    ("[::1]:8001", ("::1", 8001)),
    ("0:0::1", ("::1", None)),
    ("::ffff:10.0.0.7", ("10.0.0.7", None)),
])
def test_the_sender_forms_accepted(given: str | tuple[str, int], accepted: tuple[str, int | None]) -> None:
    assert NgimuClient(NgimuConfig(sender=given)).sender == accepted
    assert parse_sender(given) == accepted


@pytest.mark.parametrize(("fields", "message"), [
    ({"sender": "imu.local"}, r"NgimuConfig\.sender must be an IP address"),
    ({"sender": ("imu.local", 8001)}, r"NgimuConfig\.sender must be an IP address"),
    ({"sender": "10.0.0.7:port"}, r"NgimuConfig\.sender port"),
    ({"sender": "10.0.0.7:0"}, r"NgimuConfig\.sender port"),
    ({"sender": ("10.0.0.7", 70000)}, r"NgimuConfig\.sender port"),
    ({"sender": ("10.0.0.7", True)}, r"NgimuConfig\.sender port"),
    ({"sender": ("10.0.0.7",)}, r"NgimuConfig\.sender must be \(IP, port\)"),
    ({"sender": 8001}, r"NgimuConfig\.sender must be"),
    ({"host": "localhost"}, r"NgimuConfig\.host"),
    ({"host": None}, r"NgimuConfig\.host"),
    ({"port": -1}, r"NgimuConfig\.port"),
    ({"port": 80.5}, r"NgimuConfig\.port must be an integer"),
    ({"max_datagrams_per_read": 0}, r"NgimuConfig\.max_datagrams_per_read"),
    ({"parse_newest": 0}, r"NgimuConfig\.parse_newest"),
])
def test_bad_config_fields_are_named(fields: dict[str, object], message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        NgimuConfig(**fields)  # type: ignore[arg-type]


def test_the_defaults_listen_on_loopback_to_the_first_sender() -> None:
    config = NgimuConfig()
    assert config.host == "127.0.0.1" and config.port == 8000 and config.sender is None
    assert NgimuClient(config).sender is None
