"""The web application: pages, the JSON API, and the two WebSockets.

Pages (static files of this package, nothing fetched from elsewhere):

* ``/display`` — the participant display; read-only, needs no token, never shows ids.
* ``/console`` — the operator console; its actions and its live socket need the session token.
* ``/questionnaire`` — the questionnaires between conditions; storing answers needs the token.

API: ``GET /api/options``, ``/api/status``, ``/api/questionnaires/schema`` are public and change
nothing; ``POST /api/trial/start``, ``/api/trial/stop``, ``/api/questionnaires`` and
``GET /api/questionnaires``, ``/api/console/status`` need the token, as do the registry and the
session plans (:mod:`bowden.web.trial_routes`, :mod:`bowden.web.questionnaire_routes`,
:mod:`bowden.web.session_routes`; the sockets: :mod:`bowden.web.sockets`). A request from a page
of another origin is refused; one from here is read (at most 32 KiB, :mod:`bowden.web.http`), its
token checked, and then validated in full before anything changes, so a refused request (403 token
or origin, 400 invalid, 409 conflict, 413 too large, 415 wrong type) changes nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import AsyncIterator, Sequence
from pathlib import Path
from typing import Final

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.middleware.trustedhost import TrustedHostMiddleware
from starlette.requests import Request
from starlette.responses import FileResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from bowden.web.http import Handler
from bowden.web.live import ROLE_CONSOLE
from bowden.web.preflight_routes import Preflight, preflight_routes
from bowden.web.questionnaire_routes import questionnaire_routes
from bowden.web.questionnaire_store import QuestionnaireStore
from bowden.web.security import TOKEN_FIELD, TOKEN_HEADER, SecurityHeaders, SessionToken
from bowden.web.session_desk import SessionDesk
from bowden.web.session_routes import session_routes
from bowden.web.sockets import socket_routes
from bowden.web.trial_routes import trial_routes
from bowden.web.trials import TrialManager

_log = logging.getLogger(__name__)

STATIC_DIR: Final = Path(__file__).parent / "static"


def create_app(
    *,
    manager: TrialManager,
    questionnaires: QuestionnaireStore,
    desk: SessionDesk,
    token: SessionToken,
    allowed_hosts: Sequence[str] = ("127.0.0.1", "localhost", "::1", "[::1]"),
    preflight: Preflight | None = None,
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
    preflight
        The checks of ``bowden check`` for the console (``GET /api/console/preflight``), or None.
    allowed_hosts
        Host names the server answers to (``Host`` header); others get 400, which stops DNS
        rebinding from reaching the API through a browser.
    """

    def authorise(request: Request, data: dict[str, object] | None = None) -> None:
        candidates: list[object] = [request.headers.get(TOKEN_HEADER)]
        if data is not None:
            candidates.append(data.pop(TOKEN_FIELD, None))
        token.require(candidates)

    def page(name: str) -> Handler:
        async def serve(request: Request) -> Response:
            return FileResponse(STATIC_DIR / name, media_type="text/html")

        return serve

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
        *trial_routes(manager, desk, authorise),
        *questionnaire_routes(questionnaires, desk, authorise),
        *session_routes(desk, authorise),
        *preflight_routes(manager, preflight, authorise),
        *socket_routes(manager, desk, token),
        Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"),
    ]
    middleware = [
        Middleware(TrustedHostMiddleware, allowed_hosts=list(allowed_hosts)),
        Middleware(SecurityHeaders),
    ]
    return Starlette(routes=routes, middleware=middleware, lifespan=lifespan)


__all__ = ["ROLE_CONSOLE", "create_app"]
