"""Input Python's JSON parser gives up on: a 4xx over HTTP, a close frame with a reason on the console socket.

``json.loads`` raises RecursionError on thousands of nested brackets and ValueError on an integer of
more than ``sys.get_int_max_str_digits()`` digits (4300); neither is a JSONDecodeError. The server
runs on 127.0.0.1 (uvicorn, as ``bowden serve`` runs it) so the test sees the frames on the wire.
"""

from __future__ import annotations

import asyncio
import json
import sys
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
import websockets

from bowden.model import CompensationModel
from bowden.store.schema import STORE_FILE_NAME
from bowden.web.server import ServeConfig, ServerThread

from .conftest import AUTH, TOKEN, store_snapshot

DIGITS = sys.get_int_max_str_digits() + 700  # 5000 with Python's default limit
DEEP = 10_000


@pytest.fixture
def server(tmp_path: Path) -> Iterator[ServerThread]:
    config = ServeConfig(store_path=tmp_path / STORE_FILE_NAME, model=CompensationModel.from_friction(k=0.12),
                         token=TOKEN, port=0)
    with ServerThread(config) as running:
        yield running


def post(url: str, body: bytes) -> tuple[int, dict[str, object]]:
    request = urllib.request.Request(
        url, data=body, method="POST", headers={**AUTH, "Content-Type": "application/json"}
    )
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            return response.status, json.loads(response.read())
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read())


@pytest.mark.parametrize(
    ("body", "error"),
    [
        (b'{"participant": "P01", "borg_rpe": ' + b"1" * DIGITS + b"}",
         f"the request body holds a number of more than {sys.get_int_max_str_digits()} digits"),
        (b'{"participant": ' + b"[" * DEEP + b"]" * DEEP + b"}",
         "the request body is not valid JSON: nested too deeply"),
    ],
    ids=["digits", "deep"],
)
def test_a_json_body_the_parser_refuses_is_a_400_naming_the_problem(server, body, error):
    path = server.web.config.store_path
    before = store_snapshot(path)
    for route in ("/api/questionnaires", "/api/trial/start", "/api/participants"):
        status, answer = post(server.url + route, body)
        assert (status, answer) == (400, {"error": error})
    assert store_snapshot(path) == before


async def _first_message(url: str, text: str) -> tuple[list[str], int | None, str | None]:
    """Send ``text`` as the console socket's first message; what came back and the close frame."""
    origin = url.replace("ws://", "http://").removesuffix("/ws/console")
    received: list[str] = []
    async with websockets.connect(url, origin=websockets.Origin(origin), max_size=None) as socket:
        await socket.send(text)
        try:
            while True:
                received.append(str(await asyncio.wait_for(socket.recv(), 10.0)))
        except websockets.ConnectionClosed as closed:
            frame = closed.rcvd
            return received, (frame.code if frame else None), (frame.reason if frame else None)


@pytest.mark.parametrize(
    ("first", "reason"),
    [
        ('{"token": ' + "1" * DIGITS + "}",
         f"the first message holds a number of more than {sys.get_int_max_str_digits()} digits"),
        ('{"token": ' + "[" * DEEP + "]" * DEEP + "}",
         "the first message is not valid JSON: nested too deeply"),
        ('{"token": "wrong-wrong-wrong-wrong"}', "wrong or missing session token"),
    ],
    ids=["digits", "deep", "wrong-token"],
)
def test_a_first_console_message_the_parser_refuses_gets_a_close_frame_with_the_reason(server, first, reason):
    url = server.url.replace("http://", "ws://") + "/ws/console"
    received, code, said = asyncio.run(_first_message(url, first))
    assert code == 1008 and said == reason
    assert [json.loads(m) for m in received] == [{"type": "error", "error": reason}]
    # The server is unharmed: the right token still opens the console.
    assert json.loads(asyncio.run(_console_hello(url)))["type"] == "trial"


async def _console_hello(url: str) -> str:
    origin = url.replace("ws://", "http://").removesuffix("/ws/console")
    async with websockets.connect(url, origin=websockets.Origin(origin)) as socket:
        await socket.send(json.dumps({"token": TOKEN}))
        return str(await asyncio.wait_for(socket.recv(), 10.0))
