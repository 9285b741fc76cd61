"""``GET /api/console/preflight``: the checks of ``bowden check``, on the console before a session.

The server gets the check as a callable (:attr:`bowden.web.server.ServeConfig.preflight`, filled by
``bowden serve`` from its own suit options) returning ``bowden check --json``'s report. It opens the
devices, so it is refused while a trial runs; it needs the session token.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Mapping

from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from bowden.errors import ConflictError, RequestError
from bowden.web.http import refusals
from bowden.web.session_routes import Authorise
from bowden.web.trials import TrialManager

Preflight = Callable[[], Mapping[str, object]]


def preflight_routes(manager: TrialManager, preflight: Preflight | None, authorise: Authorise) -> list[Route]:
    """The pre-flight route; without ``preflight`` it says this server has none."""
    lock = asyncio.Lock()

    @refusals
    async def run_preflight(request: Request) -> Response:
        authorise(request, None)
        if preflight is None:
            raise RequestError("this server has no pre-flight (bowden serve provides one)")
        if manager.running or lock.locked():
            raise ConflictError("a trial is running, or the checks are: the pre-flight opens the devices")
        async with lock:
            report = await asyncio.to_thread(preflight)
        return JSONResponse(dict(report))

    return [Route("/api/console/preflight", run_preflight, methods=["GET"])]
