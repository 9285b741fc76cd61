"""The pre-flight's judgements on what the OS and the devices say (``bowden.hardware.preflight``)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from bowden.hardware.preflight import LinkState, check_can_link, check_store, socketcan_link

# The shape of `ip -details -json link show can0` (iproute2) for a CAN interface, abridged.
IP_LINK_CAN0 = [{
    "ifindex": 4, "ifname": "can0", "flags": ["NOARP", "UP", "LOWER_UP", "ECHO"], "mtu": 16,
    "qdisc": "pfifo_fast", "operstate": "UP", "txqlen": 1000, "link_type": "can",
    "linkinfo": {"info_kind": "can", "info_data": {
        "ctrlmode": [], "state": "ERROR-ACTIVE", "berr_counter": {"tx": 0, "rx": 0}, "restart_ms": 100,
        "bittiming": {"bitrate": 1000000, "sample_point": "0.750", "tq": 50, "prop_seg": 7,
                      "phase_seg1": 7, "phase_seg2": 5, "sjw": 1, "brp": 1},
        "clock": 24000000}},
}]


def ip_says(document: Any, returncode: int = 0) -> Any:
    def run(argv: list[str], **_: Any) -> SimpleNamespace:
        assert argv[:5] == ["ip", "-details", "-json", "link", "show"]
        return SimpleNamespace(returncode=returncode, stdout=json.dumps(document))
    return run


def link_of(**changes: Any) -> list[dict[str, Any]]:
    link: list[dict[str, Any]] = json.loads(json.dumps(IP_LINK_CAN0))
    if "flags" in changes:
        link[0]["flags"] = changes["flags"]
    if "bitrate" in changes:
        link[0]["linkinfo"]["info_data"]["bittiming"]["bitrate"] = changes["bitrate"]
    if "state" in changes:
        link[0]["linkinfo"]["info_data"]["state"] = changes["state"]
    return link


def test_an_interface_up_at_one_megabit_is_ok() -> None:
    state = socketcan_link("can0", run=ip_says(IP_LINK_CAN0))
    assert state == LinkState(exists=True, up=True, bitrate=1_000_000, can_state="ERROR-ACTIVE")
    assert check_can_link("can0", state).ok


@pytest.mark.parametrize(("changes", "expected"), [
    ({"flags": ["NOARP", "ECHO"]}, "the CAN interface can0 is down: sudo ip link set can0 up type can "
                                   "bitrate 1000000"),
    ({"bitrate": 500000}, "can0 runs at 500000 bit/s, the AK motors at 1000000"),
    ({"state": "BUS-OFF"}, "can0 is BUS-OFF: nothing acknowledges its frames"),
])
def test_a_wrong_link_is_one_line_saying_what_to_do(changes: dict[str, Any], expected: str) -> None:
    result = check_can_link("can0", socketcan_link("can0", run=ip_says(link_of(**changes))))
    assert not result.ok and expected in result.message and "\n" not in result.message


def test_a_missing_interface_is_named(tmp_path: Path) -> None:
    state = socketcan_link("nocan7", run=ip_says([], returncode=1))  # `ip` fails; no sysfs entry either
    assert state == LinkState(exists=False, up=False)
    assert "no CAN interface nocan7" in check_can_link("nocan7", state).message


def test_without_iproute2_the_link_comes_from_sysfs() -> None:
    def missing(argv: list[str], **_: Any) -> Any:
        raise FileNotFoundError("ip")
    state = socketcan_link("lo", run=missing)  # every Linux has lo, flags IFF_UP
    assert state.exists and state.up and state.bitrate is None


def test_the_store_needs_room_for_the_session(tmp_path: Path) -> None:
    def free(mb: float) -> Any:
        return lambda path: SimpleNamespace(free=int(mb * 1e6))
    store = tmp_path / "study.db"
    # 60 min at 500 Hz, 480 bytes a row at most: 864 MB.
    full = check_store(store, session_s=3600.0, rate_hz=500.0, disk_usage=free(800.0))
    assert not full.ok and "800 MB free" in full.message and "864 MB" in full.message
    assert check_store(store, session_s=3600.0, rate_hz=500.0, disk_usage=free(900.0)).ok
    missing = check_store(tmp_path / "nowhere" / "study.db", session_s=60.0, rate_hz=500.0)
    assert not missing.ok and "does not exist" in missing.message
