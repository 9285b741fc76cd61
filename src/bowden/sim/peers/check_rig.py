"""The simulated suit as ``bowden check --backend sim`` sees it: peers on threads, faults injectable.

The pre-flight opens each device on its own (one fault must not hide the others), so this rig hands
out the peers' ends one at a time: a python-can ``virtual`` channel with the motor of the chosen AK
model on id 1, an NGIMU peer that sends OSC over loopback UDP to the client the check opens, and the
ADS1115 behind an smbus2-like bus. The participant's arm hangs still, as it should at a pre-flight.

Faults (``FAULTS``), injected before the check looks: ``interface-down`` (the simulated CAN link
reports down, as ``ip link`` would), ``silent-imu`` (the IMU sends nothing), ``load-cell-offset``
(the load cell reads 25 N with the cable slack), ``hot-motor`` (the motor reports 75 °C). The other
faults of the issue are real wrong settings of the check itself (``--motor-id``, ``--imu-sender``,
the disk, the model file) and need no injection.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from typing import Final

import can

from bowden.hardware.ak60_codec import AK60Limits
from bowden.sim.peers.ads1115_peer import ADS1115Peer, FakeSMBus
from bowden.sim.peers.ak60_peer import AK60Peer
from bowden.sim.peers.ngimu_peer import NgimuPeer
from bowden.sim.peers.wall_time import WallTimePlant

FAULTS: Final = ("interface-down", "silent-imu", "load-cell-offset", "hot-motor")
SIM_MOTOR_ID: Final = 1
LOAD_CELL_OFFSET_V: Final = 0.05  # the simulated amplifier's output at no load, as bowden run's suit
LOAD_CELL_VOLTS_PER_N: Final = 0.01
_channels = itertools.count()


@dataclass
class SimulatedRig:
    """The peers' ends the check opens its drivers on (see the module)."""

    can_channel: str
    link_up: bool
    plant: WallTimePlant
    smbus: FakeSMBus
    faults: frozenset[str]
    _stack: ExitStack = field(repr=False)
    imu_peer: NgimuPeer | None = None

    def start_imu(self, target: tuple[str, int] | str, rate_hz: float = 200.0) -> NgimuPeer:
        """Start the IMU sending to ``target`` (the client the check opened; a name: an LSL stream of
        that name), the arm hanging still."""
        if isinstance(target, str):
            from bowden.sim.peers.lsl_imu_peer import LslImuPeer

            peer: NgimuPeer = self._stack.enter_context(LslImuPeer(self.plant, target, rate_hz=rate_hz))
        else:
            peer = self._stack.enter_context(NgimuPeer(self.plant, target, rate_hz=rate_hz))
        peer.hold_arm_down()
        if "silent-imu" in self.faults:
            peer.pause()
        self.imu_peer = peer
        return peer


@contextmanager
def simulated_rig(limits: AK60Limits, faults: frozenset[str] = frozenset()) -> Iterator[SimulatedRig]:
    """The simulated suit for a pre-flight, its motor speaking ``limits``; everything closed on exit."""
    from bowden.sim.arm import PrescribedArm
    from bowden.sim.suit import SimulatedSuit

    unknown = sorted(set(faults) - set(FAULTS))
    if unknown:
        from bowden.errors import ParameterError

        raise ParameterError(f"--inject {unknown[0]} is not a simulated fault; known: {', '.join(FAULTS)}")
    from bowden.sim.peers.warm_up import warm_up_suit

    warm_up_suit(PrescribedArm.hold(0.0))  # the motor's 0.1 s to answer must not pay for compiling
    plant = WallTimePlant(SimulatedSuit(arm=PrescribedArm.hold(0.0)))  # the arm hangs
    channel = f"bowden-check-{next(_channels)}"
    with ExitStack() as stack:
        peer_bus = stack.enter_context(can.Bus(interface="virtual", channel=channel))
        motor = stack.enter_context(AK60Peer(peer_bus, plant, motor_id=SIM_MOTOR_ID, limits=limits))
        if "hot-motor" in faults:
            motor.override_temperature(75.0)
        adc = ADS1115Peer(plant, offset_v=LOAD_CELL_OFFSET_V, volts_per_newton=LOAD_CELL_VOLTS_PER_N)
        if "load-cell-offset" in faults:
            adc.override_tension_n(25.0)
        smbus = stack.enter_context(FakeSMBus(adc))
        plant.start()
        yield SimulatedRig(can_channel=channel, link_up="interface-down" not in faults, plant=plant,
                           smbus=smbus, faults=frozenset(faults), _stack=stack)
