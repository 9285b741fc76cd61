"""The HTTP API of the registry and the session plans (every route needs the session token).

``GET /api/participants``, ``POST /api/participants`` (register once);
``POST /api/sessions`` (``{"participant", "seed"?}``: the participant's unfinished session, or a new
plan), ``GET /api/sessions/current`` (the session the console shows; after a restart the newest),
``GET /api/sessions/{id}``, ``POST /api/sessions/{id}/next`` (start the next trial of the plan),
``POST /api/sessions/{id}/redo`` and ``/skip`` (``{"position", "reason"}``).
"""

from __future__ import annotations

import json
from collections.abc import Callable

from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from bowden.errors import RequestError
from bowden.web.http import payload, refusals
from bowden.web.live import encode
from bowden.web.registry import parse_participant
from bowden.web.session_desk import SessionDesk, reason_text
from bowden.web.validation import integer_in, no_unknown_fields, participant_id

Authorise = Callable[[Request, "dict[str, object] | None"], None]


def _session_id(request: Request) -> int:
    return integer_in(request.path_params["session_id"], 1, 10**9, "session")


def session_routes(desk: SessionDesk, authorise: Authorise) -> list[Route]:
    """The routes, guarded by ``authorise`` (the token check of the application)."""

    @refusals
    async def list_participants(request: Request) -> Response:
        authorise(request, None)
        return JSONResponse({"participants": [p.to_json() for p in desk.registry.all()]})

    @refusals
    async def register(request: Request) -> Response:
        data = await payload(request)
        authorise(request, data)
        participant = parse_participant(data)
        created = desk.registry.register(participant)
        return JSONResponse(
            {"registered": created, **participant.to_json()}, status_code=201 if created else 200
        )

    @refusals
    async def open_session(request: Request) -> Response:
        data = await payload(request)
        authorise(request, data)
        no_unknown_fields(data, ("participant", "seed"), "session")
        if "participant" not in data:
            raise RequestError("session: the field 'participant' is missing")
        given = data.get("seed")
        seed = given if isinstance(given, int) and not isinstance(given, bool) else None
        seed = seed if seed is not None and 0 <= seed < 2**31 else None
        if given is not None and seed is None:
            raise RequestError("seed: expected a whole number from 0 to 2147483647 (or none: one is drawn)")
        session, created = desk.open(participant_id(data["participant"]), seed=seed)
        return JSONResponse(desk.publish(session.session_id), status_code=201 if created else 200)

    @refusals
    async def current(request: Request) -> Response:
        authorise(request, None)
        if desk.current is None:
            return JSONResponse({"type": "session", "session_id": None})
        return JSONResponse(desk.status(desk.store.get(desk.current)))

    @refusals
    async def show(request: Request) -> Response:
        authorise(request, None)
        return JSONResponse(desk.status(desk.store.get(_session_id(request))))

    @refusals
    async def start_next(request: Request) -> Response:
        data = await payload(request)
        authorise(request, data)
        no_unknown_fields(data, (), "next")
        status = await desk.start_next(_session_id(request))
        return JSONResponse(json.loads(encode(status)), status_code=201)

    def decision(kind: str) -> Callable[[Request], object]:
        @refusals
        async def decide(request: Request) -> Response:
            data = await payload(request)
            authorise(request, data)
            no_unknown_fields(data, ("position", "reason"), kind)
            if "position" not in data or "reason" not in data:
                raise RequestError(f"{kind}: give the step's position and the reason")
            position = integer_in(data["position"], 1, 10_000, "position")
            reason = reason_text(data["reason"])
            act = desk.redo if kind == "redo" else desk.skip
            return JSONResponse(act(_session_id(request), position, reason))

        return decide

    return [
        Route("/api/participants", list_participants, methods=["GET"]),
        Route("/api/participants", register, methods=["POST"]),
        Route("/api/sessions", open_session, methods=["POST"]),
        Route("/api/sessions/current", current, methods=["GET"]),
        Route("/api/sessions/{session_id}", show, methods=["GET"]),
        Route("/api/sessions/{session_id}/next", start_next, methods=["POST"]),
        Route("/api/sessions/{session_id}/redo", decision("redo"), methods=["POST"]),
        Route("/api/sessions/{session_id}/skip", decision("skip"), methods=["POST"]),
    ]
