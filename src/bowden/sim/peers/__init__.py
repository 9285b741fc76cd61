"""Simulated devices that speak the real wire protocols.

Each peer stands where a real device would be and is driven by a simulated plant in wall time:

* :class:`AK60Peer` — an AK60-6 in MIT mode on a python-can bus (the ``virtual`` interface in tests);
* :class:`NgimuPeer` — an NGIMU sending OSC bundles over UDP;
* :class:`ADS1115Peer` — an ADS1115 behind an smbus2-compatible I²C bus, with the real register map.

The drivers in :mod:`bowden.hardware` cannot tell them from the real devices: the bytes on the wire
are the same, so tests of the drivers against the peers test the wire protocol, not mocks.
"""

from bowden.sim.peers.ads1115_peer import ADS1115Peer, FakeSMBus
from bowden.sim.peers.ak60_peer import AK60Peer
from bowden.sim.peers.ngimu_peer import NgimuPeer
from bowden.sim.peers.wall_time import Plant, WallTimePlant

__all__ = ["ADS1115Peer", "AK60Peer", "FakeSMBus", "NgimuPeer", "Plant", "WallTimePlant"]
