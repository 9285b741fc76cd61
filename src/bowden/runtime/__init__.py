"""The runtime: fixed-rate control loop, watchdogs and safe state, timing, the crash-safe recorder."""

from typing import TYPE_CHECKING

from bowden._lazy import lazy_exports

# Imported on first use (PEP 562): the command line's choices (the fault policies) and the light
# runtime modules should not pay for the recorder's pandas (a second of bowden --help).
_EXPORTS = {
    "ControlLoop": "bowden.runtime.loop",
    "LoopConfig": "bowden.runtime.loop",
    "LoopReport": "bowden.runtime.loop",
    "LoopState": "bowden.runtime.safety",
    "LoopTiming": "bowden.runtime.timing",
    "MonotonicClock": "bowden.runtime.clock",
    "Recorder": "bowden.runtime.recorder",
    "RecorderStats": "bowden.runtime.recorder",
    "Row": "bowden.runtime.loop",
    "SafetyConfig": "bowden.runtime.safety",
    "TimingSummary": "bowden.runtime.timing",
    "TrialInfo": "bowden.runtime.recorder",
    "ramp_torque_nm": "bowden.runtime.safety",
    "stop_on_signals": "bowden.runtime.signals",
}

if TYPE_CHECKING:
    from bowden.runtime.clock import MonotonicClock
    from bowden.runtime.loop import ControlLoop, LoopConfig, LoopReport, Row
    from bowden.runtime.recorder import Recorder, RecorderStats, TrialInfo
    from bowden.runtime.safety import LoopState, SafetyConfig, ramp_torque_nm
    from bowden.runtime.signals import stop_on_signals
    from bowden.runtime.timing import LoopTiming, TimingSummary


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


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
