"""The web application: pages, the JSON API, and the two WebSockets.

Pages (static files of this package, nothing fetched from elsewhere):

* ``/display`` — the participant display; read-only, needs no token, never shows ids.
* ``/console`` — the operator console; its actions and its live socket need the session token.
* ``/questionnaire`` — the questionnaires between conditions; storing answers needs the token.

API: ``GET /api/options``, ``/api/status``, ``/api/questionnaires/schema`` are public and change
nothing; ``POST /api/trial/start``, ``/api/trial/stop``, ``/api/questionnaires`` and
``GET /api/questionnaires``, ``/api/console/status`` need the token, as do the registry and the
session plans (:mod:`bowden.web.session_routes`). A request from a page of another origin is refused;
one from here is read (at most 32 KiB, :mod:`bowden.web.http`), its token checked, and then validated
in full before anything changes, so a refused request (403 token or origin, 400 invalid, 409
conflict, 413 too large, 415 wrong type) changes nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from collections.abc import AsyncIterator, Sequence
from pathlib import Path
from typing import Final

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from bowden.contracts import REPETITIONS_PER_TRIAL
from bowden.errors import RequestError
from bowden.web.http import Handler, form_encoded, json_value, payload, refusals
from bowden.web.labels import condition_label
from bowden.web.live import ROLE_CONSOLE, ROLE_DISPLAY, LiveHub, _Client, encode, send
from bowden.web.questionnaire_store import COLUMNS, QuestionnaireStore
from bowden.web.questionnaires import EXCEPTION_FIELD, form_scores, parse_response, questionnaire_schema
from bowden.web.security import TOKEN_FIELD, TOKEN_HEADER, SecurityHeaders, SessionToken, same_origin
from bowden.web.session_desk import SessionDesk
from bowden.web.session_routes import session_routes
from bowden.web.trials import TrialManager
from bowden.web.validation import choice, participant_id

_log = logging.getLogger(__name__)

STATIC_DIR: Final = Path(__file__).parent / "static"
AUTH_TIMEOUT_S: Final = 5.0
WS_POLICY_VIOLATION: Final = 1008
# A close frame's reason is at most 123 bytes of UTF-8 (RFC 6455 §5.5: 125 with the code); ours are ASCII.
_CLOSE_REASON_CHARS: Final = 123


def create_app(
    *,
    manager: TrialManager,
    questionnaires: QuestionnaireStore,
    desk: SessionDesk,
    token: SessionToken,
    allowed_hosts: Sequence[str] = ("127.0.0.1", "localhost", "::1", "[::1]"),
) -> Starlette:
    """The bowden web application.

    Parameters
    ----------
    manager
        Runs the trials (its hub carries the live data).
    questionnaires
        The study store's questionnaire table.
    desk
        The registry and the session plans (:mod:`bowden.web.session_routes`).
    token
        The session token operator actions and questionnaire writes need.
    allowed_hosts
        Host names the server answers to (``Host`` header); others get 400, which stops DNS
        rebinding from reaching the API through a browser.
    """
    hub: LiveHub = manager.hub
    catalogue = desk.catalogue  # the paper's conditions and speeds, the protocol's own and the store's

    def authorise(request: Request, data: dict[str, object] | None = None) -> None:
        candidates: list[object] = [request.headers.get(TOKEN_HEADER)]
        if data is not None:
            candidates.append(data.pop(TOKEN_FIELD, None))
        token.require(candidates)

    def page(name: str) -> Handler:
        async def serve(request: Request) -> Response:
            return FileResponse(STATIC_DIR / name, media_type="text/html")

        return serve

    async def options(request: Request) -> Response:
        return JSONResponse({
            "conditions": [
                {"id": c, "label": condition_label(c), "support": catalogue.support(c),
                 "custom": catalogue.is_custom(c)}
                for c in catalogue.condition_names
            ],
            "speeds": [
                {"id": s, "peak_deg_s": catalogue.peak_deg_s(s), "custom": catalogue.is_custom(s)}
                for s in catalogue.speed_names
            ],
            "repetitions": REPETITIONS_PER_TRIAL,
            "backend": manager.backend.name,
        })

    async def public_status(request: Request) -> Response:
        return JSONResponse(manager.status(console=False))

    async def schema(request: Request) -> Response:
        return JSONResponse(questionnaire_schema(catalogue))

    @refusals
    async def console_status(request: Request) -> Response:
        authorise(request)
        status = manager.status(console=True)
        status["health"] = manager.health()
        return JSONResponse(json.loads(encode(status)))

    @refusals
    async def start_trial(request: Request) -> Response:
        data = await payload(request)
        authorise(request, data)
        setup, registration = desk.registered_setup(data)
        status = await manager.start(setup)
        if registration is not None:
            await asyncio.to_thread(desk.registry.register, registration)
        return JSONResponse(json.loads(encode(status)), status_code=201)

    @refusals
    async def stop_trial(request: Request) -> Response:
        data = await payload(request)
        authorise(request, data)
        if data:
            raise RequestError(f"stop takes no fields, got {', '.join(sorted(data))[:60]}")
        return JSONResponse(json.loads(encode(manager.stop("operator stop (console)"))))

    @refusals
    async def save_questionnaire(request: Request) -> Response:
        data = await payload(request)
        authorise(request, data)
        exception = data.pop(EXCEPTION_FIELD, None)
        response, replace = parse_response(form_scores(data) if form_encoded(request) else data, catalogue)
        # In their place: only after a condition the participant ran (or an exception with a reason).
        excepted = await asyncio.to_thread(
            desk.check_questionnaire, response.participant, response.condition, exception
        )
        rows = await asyncio.to_thread(questionnaires.save, response, replace=replace, exception=excepted)
        if desk.current is not None:
            desk.publish(desk.current)
        return JSONResponse(
            {"stored": rows, "participant": response.participant, "condition": response.condition},
            status_code=201,
        )

    @refusals
    async def list_questionnaires(request: Request) -> Response:
        authorise(request)
        participant = request.query_params.get("participant")
        condition = request.query_params.get("condition")
        if participant is not None:
            participant = participant_id(participant)
        if condition is not None:
            condition = choice(condition, catalogue.condition_names, "condition")
        rows = await asyncio.to_thread(questionnaires.rows, participant, condition)
        return JSONResponse({"columns": list(COLUMNS), "rows": [list(r) for r in rows]})

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

    @contextlib.asynccontextmanager
    async def lifespan(app: Starlette) -> AsyncIterator[None]:
        manager.event_loop = asyncio.get_running_loop()  # for loops run elsewhere (bowden run --serve)
        pump = asyncio.create_task(manager.pump(), name="bowden-live-pump")
        try:
            yield
        finally:
            await manager.shutdown()
            pump.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await pump

    routes = [
        Route("/", page("index.html")),
        Route("/display", page("display.html")),
        Route("/console", page("console.html")),
        Route("/questionnaire", page("questionnaire.html")),
        Route("/api/options", options),
        Route("/api/status", public_status),
        Route("/api/questionnaires/schema", schema),
        Route("/api/console/status", console_status),
        Route("/api/trial/start", start_trial, methods=["POST"]),
        Route("/api/trial/stop", stop_trial, methods=["POST"]),
        Route("/api/questionnaires", save_questionnaire, methods=["POST"]),
        Route("/api/questionnaires", list_questionnaires, methods=["GET"]),
        *session_routes(desk, authorise),
        WebSocketRoute("/ws/display", display_socket),
        WebSocketRoute("/ws/console", console_socket),
        Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"),
    ]
    middleware = [
        Middleware(TrustedHostMiddleware, allowed_hosts=list(allowed_hosts)),
        Middleware(SecurityHeaders),
    ]
    return Starlette(routes=routes, middleware=middleware, lifespan=lifespan)


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


__all__ = ["ROLE_CONSOLE", "create_app"]
