"""The questionnaire API: its schema (public), storing answers and listing them (token).

Answers are taken only in their place: after a condition the participant ran (or with an exception
and its reason), as the session desk judges (:meth:`SessionDesk.check_questionnaire`).
"""

from __future__ import annotations

import asyncio

from starlette.requests import Request
from starlette.responses import JSONResponse, Response
from starlette.routing import Route

from bowden.web.http import form_encoded, payload, refusals
from bowden.web.questionnaire_store import COLUMNS, QuestionnaireStore
from bowden.web.questionnaires import EXCEPTION_FIELD, form_scores, parse_response, questionnaire_schema
from bowden.web.session_desk import SessionDesk
from bowden.web.session_routes import Authorise
from bowden.web.validation import choice, participant_id


def questionnaire_routes(
    questionnaires: QuestionnaireStore, desk: SessionDesk, authorise: Authorise
) -> list[Route]:
    """The routes of the questionnaires, guarded by ``authorise`` where they write or reveal ids."""
    catalogue = desk.catalogue

    async def schema(request: Request) -> Response:
        return JSONResponse(questionnaire_schema(catalogue))

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
        authorise(request, None)
        participant = request.query_params.get("participant")
        condition = request.query_params.get("condition")
        if participant is not None:
            participant = participant_id(participant)
        if condition is not None:
            condition = choice(condition, catalogue.condition_names, "condition")
        rows = await asyncio.to_thread(questionnaires.rows, participant, condition)
        return JSONResponse({"columns": list(COLUMNS), "rows": [list(r) for r in rows]})

    return [
        Route("/api/questionnaires/schema", schema),
        Route("/api/questionnaires", save_questionnaire, methods=["POST"]),
        Route("/api/questionnaires", list_questionnaires, methods=["GET"]),
    ]
