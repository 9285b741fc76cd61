"""Reading a request's body and turning bowden's refusals into JSON errors.

A request is read (at most :data:`MAX_BODY_BYTES`), its origin checked, then parsed; a problem is an
HTTP 4xx with a one-line message that names it, never a traceback, and nothing is changed.
"""

from __future__ import annotations

import json
import logging
import sys
from collections.abc import Awaitable, Callable
from typing import Final
from urllib.parse import parse_qsl

from starlette.requests import Request
from starlette.responses import JSONResponse, Response

from bowden.errors import (
    AccessDeniedError,
    BowdenError,
    ConflictError,
    ParameterError,
    RequestError,
    StoreError,
)
from bowden.web.security import same_origin

_log = logging.getLogger(__name__)

MAX_BODY_BYTES: Final = 32 * 1024


class PayloadError(Exception):
    """A body the server will not read (wrong type 415, too large 413)."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def form_encoded(request: Request) -> bool:
    """Whether the body is an HTML form (its values are all strings)."""
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    return kind == "application/x-www-form-urlencoded"


async def payload(request: Request) -> dict[str, object]:
    """The request's JSON object or form fields, size-limited, from a page of this server.

    Raises
    ------
    AccessDeniedError
        If the browser says the request comes from a page of another origin: the token alone would
        not stop a page that learnt it, and plain HTTP has no other guard (checked before the body).
    PayloadError, RequestError
        For a body that is too large, of another type, not UTF-8, not JSON, nested too deeply, holds
        a number of too many digits, or repeats a form field.
    """
    if not same_origin(dict(request.headers)):
        raise AccessDeniedError("request from a page of another origin refused: nothing was changed")
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if kind not in ("application/json", "application/x-www-form-urlencoded"):
        raise PayloadError(415, "send application/json or application/x-www-form-urlencoded")
    body = bytearray()
    async for chunk in request.stream():
        body += chunk
        if len(body) > MAX_BODY_BYTES:
            raise PayloadError(413, f"request body above {MAX_BODY_BYTES} bytes")
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError:
        raise RequestError("the request body is not UTF-8") from None
    if kind == "application/json":
        data = json_value(text, "the request body") if text.strip() else {}
        if not isinstance(data, dict):
            raise RequestError("the request body must be a JSON object")
        return data
    fields: dict[str, object] = {}
    for key, value in parse_qsl(text, keep_blank_values=True, max_num_fields=200):
        if key in fields:
            raise RequestError(f"{key[:30]}: given more than once")
        fields[key] = value
    return fields


def json_value(text: str, what: str) -> object:
    """``text`` parsed as JSON; a text Python's parser refuses is a :class:`RequestError` naming ``what``.

    Besides malformed JSON, the parser gives up on thousands of nested brackets (RecursionError) and
    on an integer of more digits than Python converts (ValueError, ``sys.get_int_max_str_digits``,
    4300 by default: the guard against quadratic-time conversion).
    """
    try:
        return json.loads(text)
    except json.JSONDecodeError as error:
        raise RequestError(f"{what} is not valid JSON: {error.msg} at {error.pos}") from None
    except RecursionError:
        raise RequestError(f"{what} is not valid JSON: nested too deeply") from None
    except ValueError:  # JSONDecodeError is one too, caught above: this is the integer-digit limit
        limit = sys.get_int_max_str_digits()
        raise RequestError(f"{what} holds a number of more than {limit} digits") from None


def error_response(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


_STATUS: Final[tuple[tuple[type[Exception], int], ...]] = (
    (AccessDeniedError, 403),
    (ConflictError, 409),
    (RequestError, 400),
    (ParameterError, 400),
    (StoreError, 503),
    (BowdenError, 503),  # a device that cannot be opened, an IMU that never streamed...
)

Handler = Callable[[Request], Awaitable[Response]]


def refusals(handler: Handler) -> Handler:
    """Turn bowden's refusals into JSON errors with the right status (the message names the field)."""

    async def wrapped(request: Request) -> Response:
        try:
            return await handler(request)
        except PayloadError as error:
            return error_response(error.status, str(error))
        except BowdenError as error:
            status = next(code for kind, code in _STATUS if isinstance(error, kind))
            if status == 403:
                _log.warning("refused %s %s: %s", request.method, request.url.path, error)
            return error_response(status, str(error))

    return wrapped
