"""The control loop's command-line options shared by ``bowden run`` and ``bowden serve``.

Watchdogs a lab may have to fit to its links (IMU over Wi-Fi, motor over CAN, a slow host), the
policies for losing an evaluation device (load cell, recording), and the real-time settings of the
loop's thread. Each flag maps onto one field of :class:`~bowden.runtime.SafetyConfig` or
:class:`~bowden.runtime.realtime.RealtimeConfig`, which validate them.
"""

from __future__ import annotations

import argparse
import math
import os

from bowden.cli._flag_errors import flag_errors
from bowden.errors import ParameterError
from bowden.runtime import SafetyConfig
from bowden.runtime.realtime import RealtimeConfig
from bowden.runtime.safety import FAULT_POLICIES
from bowden.runtime.slack import SlackTakeUp
from bowden.validation import check_number

DEFAULT_RT_PRIORITY = 50


def add_safety_arguments(parser: argparse.ArgumentParser) -> None:
    """Watchdog thresholds, fault policies and real-time settings (one group each)."""
    defaults = SafetyConfig()
    group = parser.add_argument_group("watchdogs (each stops the suit safely)")
    group.add_argument("--imu-max-age-ms", type=float, default=1e3 * defaults.imu_max_age_s,
                       help="newest IMU sample older than this "
                       f"(default {1e3 * defaults.imu_max_age_s:g} ms)")
    group.add_argument("--motor-silence-ms", type=float, default=1e3 * defaults.motor_max_silence_s,
                       help="no valid motor reply to the commands sent over this long (default "
                       f"{1e3 * defaults.motor_max_silence_s:g} ms, and at least "
                       f"{defaults.motor_min_unanswered} commands)")
    group.add_argument("--host-stall-ms", type=float, default=1e3 * defaults.host_stall_max_s,
                       help="the loop itself not scheduled for longer than this (default "
                       f"{1e3 * defaults.host_stall_max_s:g} ms; shorter stalls are counted and reported)")
    group.add_argument("--on-load-cell-lost", choices=FAULT_POLICIES, default=defaults.on_load_cell_lost,
                       help="stop (default: the tension limit is a safety limit) or continue, flagged")
    group.add_argument("--on-recorder-failure", choices=FAULT_POLICIES,
                       default=defaults.on_recorder_failure,
                       help="stop (default) or continue without recording")
    start = parser.add_argument_group("starting a trial")
    start.add_argument("--slack-take-up", choices=("on", "off"),
                       help="reel the cable in slowly to a small pretension before assisting "
                       "(default: on with --backend can, off on the simulated suit, which starts taut)")
    start.add_argument("--slack-timeout", type=float, default=SlackTakeUp().timeout_s,
                       help="longest slack take-up before it is a fault "
                       f"(default {SlackTakeUp().timeout_s:g} s)")
    timing = parser.add_argument_group("real-time settings of the loop thread")
    timing.add_argument("--rt-priority", type=int, default=DEFAULT_RT_PRIORITY,
                        help="SCHED_FIFO priority 1-99 where the OS allows it "
                        f"(default {DEFAULT_RT_PRIORITY}); 0 leaves the scheduling alone")
    timing.add_argument("--cpu", type=int, action="append", dest="cpus", metavar="N",
                        help="pin the loop thread to CPU N (repeat for several; default: any)")


def _positive_ms(flag: str, value: float) -> float:
    """A millisecond flag's value in seconds; ParameterError naming the flag unless positive."""
    if not (math.isfinite(value) and value > 0.0):
        raise ParameterError(f"{flag} must be a positive number of milliseconds, got {value:g}")
    return value / 1e3


def safety_config(args: argparse.Namespace) -> SafetyConfig:
    """The watchdog thresholds and policies of :func:`add_safety_arguments`, validated."""
    _positive_ms("--imu-max-age-ms", args.imu_max_age_ms)
    _positive_ms("--motor-silence-ms", args.motor_silence_ms)
    _positive_ms("--host-stall-ms", args.host_stall_ms)
    return SafetyConfig(imu_max_age_s=args.imu_max_age_ms / 1e3,
                        motor_max_silence_s=args.motor_silence_ms / 1e3,
                        host_stall_max_s=args.host_stall_ms / 1e3,
                        on_load_cell_lost=args.on_load_cell_lost,
                        on_recorder_failure=args.on_recorder_failure)


def slack_config(args: argparse.Namespace, pulley_radius_m: float) -> SlackTakeUp | None:
    """The slack take-up of ``--slack-take-up`` (on by default on the real suit), or None."""
    choice = args.slack_take_up or ("on" if args.backend == "can" else "off")
    if choice == "off":
        # Checked all the same (as SlackTakeUp checks it): a bad value is refused, not ignored on one
        # backend and refused on the other.
        check_number(args.slack_timeout, "--slack-timeout", 0.0, low_open=True)
        return None
    with flag_errors({"SlackTakeUp.timeout_s": "--slack-timeout"}):
        return SlackTakeUp(timeout_s=args.slack_timeout, pulley_radius_m=pulley_radius_m)


def realtime_config(args: argparse.Namespace) -> RealtimeConfig:
    """The real-time settings of :func:`add_safety_arguments`, validated."""
    if args.rt_priority and not 1 <= args.rt_priority <= 99:
        raise ParameterError(f"--rt-priority must be 1–99 (0: none), got {args.rt_priority}")
    if args.cpus and min(args.cpus) < 0:
        raise ParameterError(f"--cpu must be a CPU number ≥ 0, got {min(args.cpus)}")
    cores = os.cpu_count()
    if args.cpus and cores is not None and max(args.cpus) >= cores:
        # A typo, not a permission the OS may lack: the loop would run unpinned, said only in passing.
        raise ParameterError(f"--cpu {max(args.cpus)}: this machine has CPUs 0–{cores - 1}")
    return RealtimeConfig(priority=args.rt_priority or None,
                          cpus=frozenset(args.cpus) if args.cpus else None)
