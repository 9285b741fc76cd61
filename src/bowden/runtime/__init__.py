"""The runtime: fixed-rate control loop, watchdogs and safe state, timing, the crash-safe recorder."""

from bowden.runtime.clock import MonotonicClock
from bowden.runtime.loop import ControlLoop, LoopConfig, LoopReport, Row
from bowden.runtime.recorder import Recorder, RecorderStats, TrialInfo
from bowden.runtime.safety import LoopState, SafetyConfig, ramp_torque_nm
from bowden.runtime.signals import stop_on_signals
from bowden.runtime.timing import LoopTiming, TimingSummary

__all__ = [
    "ControlLoop",
    "LoopConfig",
    "LoopReport",
    "LoopState",
    "LoopTiming",
    "MonotonicClock",
    "Recorder",
    "RecorderStats",
    "Row",
    "SafetyConfig",
    "TimingSummary",
    "TrialInfo",
    "ramp_torque_nm",
    "stop_on_signals",
]
