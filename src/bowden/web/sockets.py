"""The two live WebSockets: the participant display's (no token, never ids) and the console's.

The console's socket needs the session token in its first message; a first message that is missing,
wrong, binary, too deep or holds too long a number is answered with an error and a close frame (code
1008, policy violation) giving the reason. Both sockets are read-only: what the browser sends after
that is ignored.
"""

from __future__ import annotations

import asyncio
import contextlib
from typing import Final

from starlette.routing import WebSocketRoute
from starlette.websockets import WebSocket, WebSocketDisconnect

from bowden.errors import RequestError
from bowden.web.http import json_value
from bowden.web.live import ROLE_CONSOLE, ROLE_DISPLAY, LiveHub, _Client, encode, send
from bowden.web.security import TOKEN_FIELD, SessionToken, same_origin
from bowden.web.session_desk import SessionDesk
from bowden.web.trials import TrialManager

AUTH_TIMEOUT_S: Final = 5.0
WS_POLICY_VIOLATION: Final = 1008
# A close frame's reason is at most 123 bytes of UTF-8 (RFC 6455 §5.5: 125 with the code); ours are ASCII.
_CLOSE_REASON_CHARS: Final = 123


def socket_routes(manager: TrialManager, desk: SessionDesk, token: SessionToken) -> list[WebSocketRoute]:
    """``/ws/display`` and ``/ws/console``."""
    hub: LiveHub = manager.hub

    async def display_socket(websocket: WebSocket) -> None:
        if not same_origin(dict(websocket.headers)):
            await websocket.close(code=WS_POLICY_VIOLATION)
            return
        await websocket.accept()
        client = hub.connect(ROLE_DISPLAY)
        send(client, encode(manager.status(console=False)))
        await _serve(websocket, client, hub)

    async def console_socket(websocket: WebSocket) -> None:
        if not same_origin(dict(websocket.headers)):
            await websocket.close(code=WS_POLICY_VIOLATION)
            return
        await websocket.accept()
        try:
            offered = await asyncio.wait_for(_offered_token(websocket), AUTH_TIMEOUT_S)
            problem = None if token.matches(offered) else "wrong or missing session token"
        except TimeoutError:
            problem = f"no session token within {AUTH_TIMEOUT_S:g} s"
        except WebSocketDisconnect:
            return
        except RequestError as error:  # a first message no parser should be asked to read
            problem = str(error)
        if problem is not None:
            # Said twice: as a message the console shows, and as the close frame's reason.
            with contextlib.suppress(Exception):
                await websocket.send_text(encode({"type": "error", "error": problem}))
                await websocket.close(code=WS_POLICY_VIOLATION, reason=problem[:_CLOSE_REASON_CHARS])
            return
        client = hub.connect(ROLE_CONSOLE)
        status = manager.status(console=True)
        send(client, encode(status))
        if desk.current is not None:  # a console (re)loaded mid-session sees the plan at once
            send(client, encode(desk.status(desk.store.get(desk.current))))
        await _serve(websocket, client, hub)

    return [WebSocketRoute("/ws/display", display_socket), WebSocketRoute("/ws/console", console_socket)]


async def _offered_token(websocket: WebSocket) -> object:
    """The ``token`` field of the socket's first message (a JSON object), or None.

    Raises
    ------
    RequestError
        If the first message is binary, not JSON, nested too deeply or holds a number of too many
        digits (the refusal's reason names which).
    WebSocketDisconnect
        If the browser left before saying anything.
    """
    message = await websocket.receive()
    if message["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(message.get("code", 1000))
    text = message.get("text")
    if text is None:
        raise RequestError("the first message must be text: a JSON object with the session token")
    offered = json_value(text, "the first message") if text.lstrip().startswith("{") else None
    return offered.get(TOKEN_FIELD) if isinstance(offered, dict) else None


async def _serve(websocket: WebSocket, client: _Client, hub: LiveHub) -> None:
    """Send the client's queued messages until it leaves; what it sends is ignored (read-only)."""

    async def forward() -> None:
        while True:
            text = await client.queue.get()
            await websocket.send_text(text)

    sender = asyncio.create_task(forward())
    try:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                break
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        hub.disconnect(client)
        sender.cancel()
        with contextlib.suppress(asyncio.CancelledError, Exception):
            await sender
