"""The simulated suit in a process of its own, as the real motor and IMU are machines of their own.

The child process runs the plant integrated to wall time and the three device peers on real
transports: the AK60-6 on a ``bowden_loopback`` CAN bus, the NGIMU sending OSC bundles over UDP to
the client's loopback address, the ADS1115 behind an :class:`~bowden.sim.link.i2c.I2CServer`. So a
stall of the loop's process is not a stall of the devices: the motor keeps answering (its replies
wait on the bus), the IMU keeps streaming, as on the suit. Where the OS allows, the child's threads
run under ``SCHED_FIFO`` (they are the devices' own processors, which a busy host does not delay).

Before it says ready, the child compiles and runs everything once (the plant's numba kernels take
tens of seconds to compile in a fresh installation), so no device is enabled before the suit can
answer. The parent talks to it over two Unix socket pairs (requests and their replies; one-way
notices from the loop, which never waits): start the plant clock, hold the arm down for the IMU
calibration, tie the arm to the loop's time 0, inject faults and read the motor's received-frame
log (tests, benchmarks). The child ends by itself when the parent goes away, and then removes the
socket files itself.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import math
import multiprocessing.connection
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any, Final, Self

from bowden.errors import HardwareError, ParameterError

if TYPE_CHECKING:
    from bowden.sim.peers.ak60_peer import ReceivedFrame

_log = logging.getLogger(__name__)

READY_TIMEOUT_S: Final = 300.0  # a first run compiles the plant: minutes on a slow, busy machine
CHILD_PRIORITY: Final = 40
DEVICE_SWITCH_INTERVAL_S: Final = 0.0005
PLANT_START_PATIENCE_S: Final = 5.0  # the IMU's first state of the running plant (the parent waits 10 s)
FAULTS: Final = {
    "motor": ("mute", "ignore_next", "inject_error", "override_temperature", "replace_next_reply",
              "garble_replies"),
    "imu": ("pause", "send_nan", "hold_arm_down", "freeze"),
    "adc": ("override_tension_n", "fail_next"),
    "i2c": ("unplug",),
    "mannequin": ("mute", "ignore_next", "inject_error", "limit_torque"),
}
TDU_MOTOR_ID: Final = 1  # the simulated suit's motor (AK60Peer's default id, the driver's)
MANNEQUIN_MOTOR_ID: Final = 2  # the bench's second motor on the suit's bus (TDU: 1)
BENCH_START_ELEVATION_RAD: Final = math.radians(20.0)


@dataclass(frozen=True)
class SuitProcessSettings:
    """What the child builds (picklable).

    Attributes
    ----------
    directory
        Where the bus and the I²C socket files live (the CAN channel is ``directory / "can"``).
    imu_target
        (host, port) the simulated NGIMU sends to.
    reference
        The reference the arm follows from the loop's time 0 (an object with ``cycle``,
        ``start_s``, ``end_s``), or None to repeat ``cycle`` from the plant's start.
    cycle
        The minimum-jerk cycle of the free-running arm.
    imu_rate_hz
        Stream rate of the simulated NGIMU.
    bench
        The mannequin bench instead of a participant: the arm is the mannequin's, driven by a second
        simulated AK-series motor (an AK80-9, id :data:`MANNEQUIN_MOTOR_ID`) on the same bus;
        ``reference`` and ``cycle`` are unused.
    motor_limits
        The MIT-mode ranges the simulated TDU speaks (an ``AK60Limits``: its AK model's and firmware's,
        ``bowden.hardware.motors``), None for the AK60-6's default.
    imu_lsl_name
        Publish the arm as an LSL quaternion stream of this name (``--imu lsl:NAME``) instead of
        sending NGIMU OSC bundles to ``imu_target``.
    """

    directory: str
    imu_target: tuple[str, int]
    reference: Any
    cycle: Any
    imu_rate_hz: float = 200.0
    bench: bool = False
    motor_limits: Any = None
    imu_lsl_name: str | None = None


class SimulatedSuitProcess:
    """The parent's handle on the simulated suit's process (a context manager).

    Parameters
    ----------
    imu_target
        The NGIMU client's bound (host, port); must be a loopback address.
    reference, cycle
        See :class:`SuitProcessSettings`.
    ready_timeout_s
        How long to wait for the child to be ready (it compiles on a first run).
    """

    def __init__(self, *, imu_target: tuple[str, int], reference: Any = None, cycle: Any = None,
                 bench: bool = False, ready_timeout_s: float = READY_TIMEOUT_S,
                 motor_limits: Any = None, imu_lsl_name: str | None = None) -> None:
        if not imu_target[0].startswith("127.") and imu_target[0] != "::1":
            raise ParameterError(f"the simulated IMU sends to loopback only, got {imu_target[0]!r}")
        if reference is None and cycle is None and not bench:
            raise ParameterError("SimulatedSuitProcess needs a reference or a cycle for the arm")
        self._directory = Path(tempfile.mkdtemp(prefix="bowden-suit-"))
        self.settings = SuitProcessSettings(directory=str(self._directory), imu_target=imu_target,
                                            reference=reference, cycle=cycle, bench=bench,
                                            motor_limits=motor_limits, imu_lsl_name=imu_lsl_name)
        self.ready_timeout_s = ready_timeout_s
        self._process: subprocess.Popen[str] | None = None
        self._requests: Connection | None = None
        self._notices: Connection | None = None
        self._lock = threading.Lock()
        self.plant_origin_s = math.nan  # time.monotonic() at plant time 0, once started
        self._stderr_tail: deque[str] = deque(maxlen=20)
        self._stderr_reader: threading.Thread | None = None
        self._ready = False
        self.loop_start_notified = False

    @property
    def can_channel(self) -> str:
        """The ``bowden_loopback`` channel of the suit's CAN bus."""
        return str(self._directory / "can")

    @property
    def i2c_path(self) -> str:
        """The socket file of the suit's I²C bus."""
        return str(self._directory / "i2c.sock")

    @property
    def pid(self) -> int | None:
        return self._process.pid if self._process is not None else None

    # --- lifecycle -------------------------------------------------------------------------------
    def start(self, announce: Callable[[str], None] | None = None) -> Self:
        """Start the child and wait until its devices answer.

        Raises
        ------
        HardwareError
            If the child dies or is not ready in time (with its own error message).
        """
        if self._process is not None:
            # A second child would share the first's socket directory, and the first, orphaned,
            # would remove it when it ends.
            raise RuntimeError("the simulated suit's process is already started")
        # A fresh interpreter (not a fork of this one with its threads and sockets, and not
        # multiprocessing's spawn, which would re-run the caller's main script), talking over two
        # socket pairs: requests and replies, and one-way notices from the loop.
        parent_requests, child_requests = socket.socketpair()
        notice_writer, notice_reader = socket.socketpair()
        fds = (child_requests.fileno(), notice_reader.fileno())
        try:
            process = subprocess.Popen(
                [sys.executable, "-m", "bowden.sim.link.suit_process", str(fds[0]), str(fds[1]),
                 str(os.getpid())],
                pass_fds=fds, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                text=True,
            )
        finally:
            child_requests.close()
            notice_reader.close()
        self._process = process
        self._stderr_tail.clear()
        self._ready = False
        # The child's stderr is drained all along (a full pipe would stall the devices), its last
        # lines kept for an error message; once it is ready, what it writes is logged.
        self._stderr_reader = threading.Thread(target=self._drain_stderr, args=(process,),
                                               name="suit-stderr", daemon=True)
        self._stderr_reader.start()
        self._requests = Connection(parent_requests.detach())
        self._notices = Connection(notice_writer.detach())
        try:
            self._requests.send(self.settings)
        except OSError:  # the child is gone (killed before it read its settings)
            raise self._ended_before_ready(process) from None
        except Exception as error:  # pickle's errors have no common base
            self.close()
            raise ParameterError(f"the simulated suit's settings cannot be sent to its process (the "
                                 f"reference must be picklable): {type(error).__name__}: {error}") from None
        started = time.monotonic()
        announced = False
        while not self._requests.poll(0.2):
            if process.poll() is not None:
                message = self._child_error()
                self.close()
                raise HardwareError(f"the simulated suit's process ended before it was ready "
                                    f"(exit code {process.returncode}){message}")
            if announce is not None and not announced and time.monotonic() > started + 3.0:
                announce("preparing the simulated suit (a first run compiles it: up to a minute or two)")
                announced = True
            if time.monotonic() > started + self.ready_timeout_s:
                self.close()
                raise HardwareError(f"the simulated suit was not ready within {self.ready_timeout_s:g} s")
        try:
            kind, detail = self._requests.recv()
        except (EOFError, OSError):  # it closed its end, or died: it is ending
            raise self._ended_before_ready(process) from None
        if kind != "ready":
            self.close()
            raise HardwareError(f"the simulated suit could not start: {' '.join(str(detail).split())}")
        self._ready = True
        return self

    def _ended_before_ready(self, process: subprocess.Popen[str]) -> HardwareError:
        """The error for a child that went away before it said ready, once it has ended (closed)."""
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(timeout=10.0)
        message = self._child_error()
        self.close()
        return HardwareError(f"the simulated suit's process ended before it was ready "
                             f"(exit code {process.returncode}){message}")

    def _drain_stderr(self, process: subprocess.Popen[str]) -> None:
        stream = process.stderr
        if stream is None:
            return
        with contextlib.suppress(OSError, ValueError):  # closed under us
            for line in stream:
                text = line.rstrip()
                if not text:
                    continue
                self._stderr_tail.append(text)
                if self._ready:
                    _log.warning("simulated suit (pid %d): %s", process.pid, text)

    def _child_error(self) -> str:
        """The last line the child wrote to stderr, once it has ended (for a one-line error message)."""
        process, reader = self._process, self._stderr_reader
        if process is None or process.poll() is None:
            return ""
        if reader is not None:
            reader.join(timeout=2.0)  # everything it wrote, up to the end of the pipe
        return f": {self._stderr_tail[-1].strip()}" if self._stderr_tail else ""

    def close(self) -> None:
        """Stop the child (politely, then by force) and remove its socket files."""
        process = self._process
        if process is not None:
            if process.poll() is None and not self._ready:
                process.kill()  # still preparing (or never will be): nothing to stop politely
            elif process.poll() is None and self._requests is not None:
                try:
                    with self._lock:
                        self._requests.send(("stop", None, ()))
                except (OSError, ValueError):
                    pass
            try:
                process.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(timeout=5.0)
            if self._stderr_reader is not None:
                self._stderr_reader.join(timeout=2.0)
                self._stderr_reader = None
            if process.stderr is not None:
                process.stderr.close()
            self._process = None
            self._ready = False
        for connection in (self._requests, self._notices):
            if connection is not None:
                connection.close()
        self._requests = self._notices = None
        shutil.rmtree(self._directory, ignore_errors=True)

    def __enter__(self) -> Self:
        # ``with suit.start(...)`` (start to pass an announcer, then manage) enters a running suit.
        return self if self._process is not None else self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # --- requests --------------------------------------------------------------------------------
    def _call(self, target: str, method: str | None, *args: Any) -> Any:
        if self._requests is None:
            raise HardwareError("the simulated suit is not running")
        with self._lock:
            try:
                self._requests.send((target, method, args))
                if not self._requests.poll(10.0):
                    raise HardwareError(f"the simulated suit did not answer {target}.{method}")
                kind, result = self._requests.recv()
            except (EOFError, OSError) as error:
                raise HardwareError(f"the simulated suit's process is gone ({error})") from None
        if kind == "error":
            raise HardwareError(f"the simulated suit refused {target}.{method}: {result}")
        return result

    def start_plant(self) -> float:
        """Let the plant's time run from now on; returns ``time.monotonic()`` at plant time 0, once the
        IMU has sent a state of the running plant (what a client reads next is no calibration pose)."""
        self.plant_origin_s = float(self._call("plant", "start"))
        return self.plant_origin_s

    def hold_arm_down(self, held: bool = True) -> None:
        """The simulated IMU reports a still, hanging arm (the calibration pose) while ``held``."""
        self._call("imu", "hold_arm_down", held)

    def loop_started(self, monotonic_s: float) -> None:
        """Tell the arm when loop time 0 was (``time.monotonic()``); never waits (called in the loop)."""
        if self._notices is None or self.loop_start_notified:
            return
        self.loop_start_notified = True
        # A one-way pipe of its own, so that the loop never queues behind a fault-injection request.
        self._notices.send(("loop_started", monotonic_s))

    def inject(self, target: str, method: str, *args: Any) -> Any:
        """Call a fault injection of a device peer in the child and return its result.

        Parameters
        ----------
        target, method
            A key of ``FAULTS`` and one of its faults: ``motor`` (:class:`~bowden.sim.peers.AK60Peer`:
            ``mute(bool)``, ``ignore_next(n)``, ``inject_error(code)``, ``override_temperature(°C or
            None)``, ``replace_next_reply(hex string)``, ``garble_replies(bool)``), ``imu``
            (:class:`~bowden.sim.peers.NgimuPeer`: ``pause(bool)``, ``send_nan(bool)``,
            ``hold_arm_down(bool)``, ``freeze(bool)``), ``mannequin`` (the bench's second motor, an
            :class:`~bowden.sim.peers.AK60Peer`: ``mute``, ``ignore_next``, ``inject_error``, and
            ``limit_torque(Nm)``: too weak for its load), ``adc`` (:class:`~bowden.sim.peers.ADS1115Peer`:
            ``override_tension_n(N or None)``, ``fail_next(n)``) or ``i2c`` (``unplug()``: the I²C
            server stops answering for good, every transfer times out).
        *args
            The fault's arguments (picklable).

        Raises
        ------
        ParameterError
            For an unknown fault (nothing is sent).
        HardwareError
            If the peer refused the arguments or the child is gone.
        """
        if method not in FAULTS.get(target, ()):
            raise ParameterError(f"no fault injection {target}.{method}; known: {FAULTS}")
        return self._call(target, method, *args)

    def plant_time_s(self) -> float:
        """The plant's current time (s) as the child sees it."""
        return float(self._call("plant", "time"))

    def received_frames(self, since_s: float = -math.inf, device: str = "motor") -> list[ReceivedFrame]:
        """The frames the simulated motor (``device`` "mannequin": the bench's mannequin motor) heard
        at or after ``since_s`` (``time.monotonic()``, s).

        Returns
        -------
        list of ReceivedFrame
            Oldest first: wall time (s, ``time.monotonic()``), kind (enter/exit/zero/command) and the
            torque applied (Nm) for commands.
        """
        from bowden.sim.peers.ak60_peer import ReceivedFrame

        rows = self._call(device, "received", float(since_s))
        return [ReceivedFrame(time_s=t, kind=kind, torque_nm=torque) for t, kind, torque in rows]


# --- the child --------------------------------------------------------------------------------------
def _motor_node(directory: Path, motor_id: int) -> Any:
    """A simulated motor's own node on the suit's bus, accepting only standard frames to its id (what
    its firmware answers): the bench's two motors no longer wake for each other's frames."""
    import can  # the child's: the parent does not need python-can to start it

    return can.Bus(interface="bowden_loopback", channel=str(directory / "can"),
                   can_filters=[{"can_id": motor_id, "can_mask": 0x7FF, "extended": False}])


def _warm_up(cycle: Any) -> None:
    """Compile and run everything the devices use once, so that the first frame is answered in time
    (``cycle`` None: the bench's mannequin arm)."""
    from bowden.sim.arm import MannequinArm, PrescribedArm
    from bowden.sim.peers.warm_up import warm_up_suit

    warm_up_suit(PrescribedArm.following(cycle) if cycle is not None else MannequinArm(load_torque_nm=1.0))


def _child_main(requests: Connection, notices: Connection, parent_pid: int) -> None:
    """Entry point of the suit's process: build, warm up, say ready, serve until told to stop."""
    # Ctrl-C reaches the whole terminal's process group: the parent stops the suit, not the signal.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    settings = requests.recv()
    try:
        # Compiling takes seconds of CPU: at a real-time priority it would starve the machine.
        _warm_up(None if settings.bench else
                 settings.cycle if settings.cycle is not None else settings.reference.cycle)
        # The devices' threads inherit the policy; refused, it is a normal process: it works, only
        # less like separate hardware.
        with contextlib.suppress(AttributeError, OSError):
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(CHILD_PRIORITY))
        # The devices share one interpreter lock: a device that wakes while another holds it gets it
        # within 0.5 ms, not Python's 5 (as the loop's real-time settings do for its process).
        sys.setswitchinterval(DEVICE_SWITCH_INTERVAL_S)
        devices = _ChildDevices(settings)
    except BaseException as error:
        traceback.print_exc()
        try:
            requests.send(("error", f"{type(error).__name__}: {error}"))
        except OSError:  # the parent is gone: nobody else will remove the directory
            shutil.rmtree(settings.directory, ignore_errors=True)
        return
    # The motors' received-frame logs grow to hundreds of thousands of objects; a full collection
    # over them stalls every device for tens of ms (measured: a simulated motor silent for 32 ms).
    # So only the young generations are collected, by the serve loop, between requests.
    gc.collect()
    gc.freeze()
    gc.disable()
    orphaned = True
    try:
        requests.send(("ready", None))
        orphaned = devices.serve(requests, notices, parent_pid)
    except OSError:
        pass  # the parent went away before we were ready
    finally:
        devices.close()
        if orphaned:
            # Nobody is left to clean up: the socket files go with the devices.
            shutil.rmtree(settings.directory, ignore_errors=True)


class _ChildDevices:
    """The plant and its peers in the child."""

    def __init__(self, settings: SuitProcessSettings) -> None:

        from bowden.hardware.ak60_codec import limits_for_motor
        from bowden.sim.arm import ArmDriver, MannequinArm, PrescribedArm
        from bowden.sim.arm_follower import ArmFollowingTheLoop
        from bowden.sim.link.i2c import I2CServer
        from bowden.sim.peers import ADS1115Peer, AK60Peer, FakeSMBus, NgimuPeer, WallTimePlant
        from bowden.sim.peers.mannequin import MannequinJoint
        from bowden.sim.suit import SimulatedSuit

        directory = Path(settings.directory)
        self.follower = None
        arm: ArmDriver
        mannequin_arm: MannequinArm | None = None
        if settings.bench:
            arm = mannequin_arm = MannequinArm(initial_elevation_rad=BENCH_START_ELEVATION_RAD)
        else:
            if settings.reference is not None:
                self.follower = ArmFollowingTheLoop(settings.reference)
            arm = (self.follower.arm() if self.follower is not None
                   else PrescribedArm.following(settings.cycle))
        self.plant = WallTimePlant(SimulatedSuit(arm=arm))
        if self.follower is not None:
            self.follower.plant = self.plant
        self._closers: list[Any] = []
        self.bus = _motor_node(directory, TDU_MOTOR_ID)
        self._closers.append(self.bus.shutdown)
        self.motor = AK60Peer(self.bus, self.plant, motor_id=TDU_MOTOR_ID,
                              limits=settings.motor_limits).start()
        self._closers.insert(0, self.motor.close)
        self.mannequin: AK60Peer | None = None
        self.mannequin_joint: MannequinJoint | None = None
        if mannequin_arm is not None:
            # Its own node on the bus (two peers reading one node would take each other's frames).
            mannequin_bus = _motor_node(directory, MANNEQUIN_MOTOR_ID)
            self._closers.append(mannequin_bus.shutdown)
            limits = limits_for_motor("AK80-9")
            self.mannequin_joint = joint = MannequinJoint(self.plant, mannequin_arm,
                                                          torque_limit_nm=limits.torque_nm)
            self.mannequin = AK60Peer(mannequin_bus, joint, motor_id=MANNEQUIN_MOTOR_ID,
                                      limits=limits).start()
            self._closers.insert(0, self.mannequin.close)
        if settings.imu_lsl_name is not None:
            from bowden.sim.peers.lsl_imu_peer import LslImuPeer

            self.imu: NgimuPeer = LslImuPeer(self.plant, settings.imu_lsl_name,
                                             rate_hz=settings.imu_rate_hz).start()
        else:
            self.imu = NgimuPeer(self.plant, settings.imu_target, rate_hz=settings.imu_rate_hz).start()
        self._closers.insert(0, self.imu.close)
        self.adc = ADS1115Peer(self.plant, offset_v=0.05, volts_per_newton=0.01)
        self.i2c = I2CServer(FakeSMBus(self.adc), directory / "i2c.sock").start()
        self._closers.insert(0, self.i2c.close)

    def serve(self, requests: Connection, notices: Connection, parent_pid: int) -> bool:
        """Answer the parent until it says stop (False) or goes away (True: nobody will clean up)."""
        listening: list[Connection] = [requests, notices]
        while True:
            ready = multiprocessing.connection.wait(listening, timeout=0.1)
            gc.collect(1)  # young objects only: short, and cycles among them are freed
            if notices in ready:
                try:
                    kind, value = notices.recv()
                except EOFError:
                    listening.remove(notices)
                    continue
                if kind == "loop_started" and self.follower is not None:
                    self.follower.plant_time_at_loop_start_s = value - self.plant.origin_s
            if requests not in ready:
                if os.getppid() != parent_pid:
                    return True  # the parent died: nobody will stop us
                continue
            try:
                target, method, args = requests.recv()
            except (EOFError, OSError):
                return True
            if target == "stop":
                return False
            try:
                result = self._handle(target, method, args)
                reply: tuple[str, Any] = ("ok", result)
            except Exception as error:
                reply = ("error", f"{type(error).__name__}: {error}")
            try:
                requests.send(reply)
            except OSError:
                return True

    def _handle(self, target: str, method: str, args: tuple[Any, ...]) -> Any:
        if target == "plant":
            if method == "start":
                self.plant.start()
                # The IMU sends nothing before the plant runs, so the client's latest sample is still
                # the held calibration pose: answer once a state of the running plant is on the wire.
                self.imu.wait_until_sent(timeout_s=PLANT_START_PATIENCE_S)
                return self.plant.origin_s
            if method == "time":
                return self.plant.plant_time_s()
        if target in ("motor", "mannequin") and method == "received":
            peer = self.motor if target == "motor" else self.mannequin
            if peer is None:
                raise ParameterError("no mannequin motor on this simulated suit")
            return [(f.time_s, f.kind, f.torque_nm) for f in peer.commands_since(float(args[0]))]
        if method in FAULTS.get(target, ()):
            if target == "i2c":
                self.i2c.silent = True
                return None
            if method == "limit_torque":  # the mannequin's motor too weak for its load
                if self.mannequin_joint is None:
                    raise ParameterError("no mannequin motor on this simulated suit")
                self.mannequin_joint.torque_limit_nm = float(args[0])
                return None
            devices = {"motor": self.motor, "imu": self.imu, "adc": self.adc, "mannequin": self.mannequin}
            device = devices[target]
            if device is None:
                raise ParameterError(f"no {target} on this simulated suit")
            if method == "replace_next_reply":
                args = (bytes.fromhex(args[0]),)
            return getattr(device, method)(*args)
        raise ParameterError(f"unknown request {target}.{method}")

    def close(self) -> None:
        for close in self._closers:
            try:
                close()
            except Exception:
                _log.exception("closing the simulated suit")


if __name__ == "__main__":
    _child_main(Connection(int(sys.argv[1])), Connection(int(sys.argv[2])), int(sys.argv[3]))
