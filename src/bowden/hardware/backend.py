"""An open suit as the control loop sees it (real devices or the simulated suit's)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bowden.hardware.protocols import Clock, ElevationSensor, Motor, TensionSensor


@dataclass
class Backend:
    """The devices of one run, plus what the run summary reports on.

    Attributes
    ----------
    motor, imu, clock, load_cell
        The devices (the sensors stamp their samples with ``clock``).
    reference_elevation
        Reference elevation (rad) at loop time t when the suit itself follows one (the simulated
        arm), for the recording; None for the real suit.
    describe
        One line naming the devices ("AK60-6 id 1 on socketcan:can0").
    inject
        Fault injection into a simulated suit's devices, ``inject(device, fault, *args)`` (tests and
        benchmarks); None for real hardware.
    simulation
        The handle on a simulated suit running in its own process
        (:class:`bowden.sim.link.suit_process.SimulatedSuitProcess`: its pid, socket paths, plant
        clock and received-frame log, for tests and benchmarks); None otherwise.
    mannequin
        On the mannequin bench, the mannequin's own motor (torque > 0 loads the arm down); None on
        the suit.
    """

    motor: Motor
    imu: ElevationSensor
    clock: Clock
    load_cell: TensionSensor | None = None
    reference_elevation: Callable[[float], float] | None = None
    describe: str = ""
    inject: Callable[..., Any] | None = None
    simulation: object | None = None
    mannequin: Any = None
