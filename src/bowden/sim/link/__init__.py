"""The simulated suit in its own process, and the loopback transports between it and the loop.

* :mod:`~bowden.sim.link.can_bus` — a python-can interface (``bowden_loopback``) over Unix datagram
  sockets: a CAN bus that crosses processes and never leaves the machine;
* :mod:`~bowden.sim.link.i2c` — I²C transactions forwarded to another process;
* :mod:`~bowden.sim.link.suit_process` — the process running the simulated suit's device peers.
"""
