"""Two simulated motors behind one node of the ``bowden_loopback`` bus (the bench's child process):
each answers its own id once, the drivers on nodes of their own (as the bench's parent has them)
get their own motor's replies, and the node hears each frame once."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import can
import pytest
from tests.hardware.test_ak60_wire import FAST, exchange

from bowden.hardware.ak60 import AK60Motor
from bowden.sim.peers import AK60Peer, WallTimePlant
from bowden.sim.peers.ak60_peer import COMMAND, SharedNode

if TYPE_CHECKING:
    from conftest import SimplePlant


class CountingBus(can.BusABC):
    """A bus that counts the frames it hands out (the node's wake-ups)."""

    def __init__(self, bus: can.BusABC) -> None:
        self.inner, self.heard = bus, 0
        super().__init__(channel=bus.channel_info)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self.inner.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        message = self.inner.recv(timeout)
        self.heard += message is not None
        return message, False


def test_two_motors_on_one_node_answer_their_own_ids_once(tmp_path: Path, plant: SimplePlant) -> None:
    channel = str(tmp_path / "can")
    plants = plant, type(plant)()
    walls = [WallTimePlant(plant) for plant in plants]
    for wall in walls:
        wall.start()
    with can.Bus(interface="bowden_loopback", channel=channel) as node_bus, \
            can.Bus(interface="bowden_loopback", channel=channel) as first_bus, \
            can.Bus(interface="bowden_loopback", channel=channel) as second_bus:
        node_side = CountingBus(node_bus)
        peers = AK60Peer(node_side, walls[0], motor_id=1), AK60Peer(node_side, walls[1], motor_id=2)
        node = SharedNode(node_side, peers).start()
        try:
            first = AK60Motor(first_bus, FAST)
            second = AK60Motor(second_bus, replace(FAST, motor_id=2))
            first.enable()
            second.enable()
            for _ in range(20):
                exchange(first, 1.0)
                exchange(second, -2.0)
            first.disable()
            second.disable()
        finally:
            node.close()
            node_side.shutdown()
    for peer, torque in zip(peers, (1.0, -2.0), strict=True):
        commands = [frame for frame in peer.received if frame.kind == COMMAND]
        assert len(commands) == 20  # each command answered by its own motor only, once
        assert all(frame.torque_nm == pytest.approx(torque, abs=30.0 / 4095) for frame in commands)
    # Each driver's frames (enter, 20 commands, exit: 22 each) heard once by the node, and neither
    # motor's replies came back to it.
    assert node_side.heard == 44
    assert plants[0].motor.torque_nm > 0.0 > plants[1].motor.torque_nm
