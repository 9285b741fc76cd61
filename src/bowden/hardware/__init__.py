"""Device protocols and the real drivers (AK60-6 over CAN, NGIMU over OSC/UDP, ADS1115 over I2C).

The protocols in :mod:`bowden.hardware.protocols` are what the runtime loop talks to; the simulated
suit in :mod:`bowden.sim` implements them too, so the loop cannot tell the two apart.
"""

from bowden.hardware.protocols import (
    Clock,
    ElevationSample,
    ElevationSensor,
    Motor,
    MotorState,
    TensionSample,
    TensionSensor,
)

__all__ = [
    "Clock",
    "ElevationSample",
    "ElevationSensor",
    "Motor",
    "MotorState",
    "TensionSample",
    "TensionSensor",
]
