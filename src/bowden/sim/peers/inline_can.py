"""A CAN bus on which the simulated motor answers inside the sender's own call.

The threaded peers (:class:`~bowden.sim.peers.AK60Peer` on python-can's ``virtual`` bus) answer in
wall time, which suits a plant integrated to wall time. The console's simulated suit instead runs
its physics in steps paced to the wall clock, possibly faster than real time (``bowden serve
--time-scale``): a peer thread would answer a variable number of simulated milliseconds late. On
an :class:`InlineCanBus` pair the peer handles each frame the moment the driver sends it, so the
driver finds the reply waiting when it polls, whatever the time scale and however busy the host;
the frames are still the real MIT-mode bytes of both ends (:mod:`bowden.hardware.ak60_codec`).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

import can


class InlineCanBus(can.BusABC):
    """One end of a synchronous bus pair (:func:`inline_can_pair`): what it sends is handed to the
    other end's ``deliver`` at once; what it is handed waits in its queue for :meth:`recv`."""

    def __init__(self, channel: str = "inline", **kwargs: Any) -> None:
        super().__init__(channel=channel, **kwargs)
        self.channel_info = f"inline CAN bus {channel}"
        self.deliver: Callable[[can.Message], None] = self._drop
        self._queue: deque[can.Message] = deque()

    @staticmethod
    def _drop(message: can.Message) -> None:
        return None  # nothing at the other end yet: as an unterminated bus, the frame is lost

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.deliver(msg)

    def enqueue(self, message: can.Message) -> None:
        """A frame from the other end, for this end's next :meth:`recv`."""
        self._queue.append(message)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        # Nothing can arrive while the caller waits: every frame was queued by a send that returned.
        return (self._queue.popleft() if self._queue else None), False

    def shutdown(self) -> None:
        self._queue.clear()
        super().shutdown()


def inline_can_pair(channel: str = "inline") -> tuple[InlineCanBus, InlineCanBus]:
    """Two ends of one synchronous bus: (the driver's, the peer's).

    The peer's end is wired to the driver's queue; the caller wires the driver's end to the peer
    (``driver.deliver = peer.answer``) once the peer exists.
    """
    driver, peer = InlineCanBus(channel), InlineCanBus(channel)
    peer.deliver = driver.enqueue
    return driver, peer
