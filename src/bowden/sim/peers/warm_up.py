"""Compile the simulated suit before its devices are asked to answer in real time.

The plant's numba kernels compile on their first call: tens of seconds in a fresh installation (an
empty cache), more on a busy machine. A peer that first touches the plant while a driver waits for
its reply (a motor's 0.1 s to enter motor mode, a load cell's first conversion) would miss that
window on a fresh checkout only, so whoever starts peers in wall time warms a throwaway suit first.
"""

from __future__ import annotations

from typing import Any


def warm_up_suit(arm: Any) -> None:
    """Compile and run once everything the devices use, on a throwaway suit moved by ``arm``.

    ``arm`` is a fresh arm of the kind the real suit will have (a prescribed arm, or the mannequin's:
    its physics is another kernel); it is consumed.
    """
    from bowden.sim.peers.ngimu_peer import NgimuPeer
    from bowden.sim.peers.wall_time import WallTimePlant
    from bowden.sim.suit import SimulatedSuit

    suit = SimulatedSuit(arm=arm)
    suit.motor.enable()
    suit.motor.command_torque(0.5)
    suit.advance_to(0.05)
    suit.motor.command_impedance(0.0, 0.5, 30.0, 0.6, 0.0)
    suit.advance_to(0.1)
    suit.elevation_sensor.read()
    suit.tension_sensor.read()
    imu = NgimuPeer(WallTimePlant(suit), ("127.0.0.1", 9))  # encodes bundles; nothing is sent
    imu.datagrams(0.3, 0.1)
    imu.close()
