"""The trial API: the options a console offers, the status, and starting and stopping a trial.

``GET /api/options`` and ``/api/status`` are public and change nothing; ``GET /api/console/status``,
``POST /api/trial/start`` and ``/api/trial/stop`` need the session token (``authorise``).
"""

from __future__ import annotations

import asyncio
import json

from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from bowden.contracts import REPETITIONS_PER_TRIAL
from bowden.errors import RequestError
from bowden.web.http import payload, refusals
from bowden.web.labels import condition_label
from bowden.web.live import encode
from bowden.web.session_desk import SessionDesk
from bowden.web.session_routes import Authorise
from bowden.web.trials import TrialManager


def trial_routes(manager: TrialManager, desk: SessionDesk, authorise: Authorise) -> list[Route]:
    """The routes of the trials, guarded by ``authorise`` where they act or reveal ids."""
    catalogue = desk.catalogue  # the paper's conditions and speeds, the protocol's own and the store's

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

    @refusals
    async def console_status(request: Request) -> Response:
        authorise(request, None)
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

    return [
        Route("/api/options", options),
        Route("/api/status", public_status),
        Route("/api/console/status", console_status),
        Route("/api/trial/start", start_trial, methods=["POST"]),
        Route("/api/trial/stop", stop_trial, methods=["POST"]),
    ]
