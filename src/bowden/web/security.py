"""The session token, its constant-time check, and the HTTP headers every response carries.

``bowden serve`` makes a fresh random token at start and prints it. Every operator action and every
questionnaire write must carry it, in the ``X-Bowden-Token`` header (what the pages' scripts send)
or a ``token`` form field (plain HTML forms, scripts); the participant display needs none and can
change nothing. The token is never put in a cookie, so another web site cannot make the browser
send it (no cross-site request forgery), and the pages keep it in ``sessionStorage`` after reading
it from the URL fragment, which browsers never send to the server (so it stays out of logs).

The comparison is :func:`hmac.compare_digest` on the UTF-8 bytes: its time does not depend on how
many leading characters of a guess are right.
"""

from __future__ import annotations

import hmac
import secrets
from collections.abc import Iterable
from typing import Final

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from bowden.errors import AccessDeniedError, ParameterError

TOKEN_HEADER: Final = "x-bowden-token"
TOKEN_FIELD: Final = "token"
_TOKEN_BYTES: Final = 32  # 256 bits of randomness; 43 URL-safe characters

CONTENT_SECURITY_POLICY: Final = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; frame-ancestors 'none'"
)
SECURITY_HEADERS: Final = (
    (b"content-security-policy", CONTENT_SECURITY_POLICY.encode()),
    (b"x-content-type-options", b"nosniff"),
    (b"x-frame-options", b"DENY"),
    (b"referrer-policy", b"no-referrer"),
    (b"cache-control", b"no-store"),
    (b"cross-origin-opener-policy", b"same-origin"),
)


class SessionToken:
    """The secret of one server session.

    Parameters
    ----------
    value
        The token; None draws a fresh one from :mod:`secrets`. A given value must have at least 16
        characters (tests and scripts may fix it; nobody should guess it).
    """

    def __init__(self, value: str | None = None) -> None:
        if value is None:
            value = secrets.token_urlsafe(_TOKEN_BYTES)
        if not isinstance(value, str) or len(value) < 16 or not value.isprintable() or " " in value:
            raise ParameterError("the session token must be at least 16 printable characters without spaces")
        self._secret = value.encode()
        self.value = value

    def matches(self, candidate: object) -> bool:
        """Whether ``candidate`` is the token (constant time in the position of the first difference)."""
        if not isinstance(candidate, str):
            return False
        return hmac.compare_digest(candidate.encode(), self._secret)

    def require(self, candidates: Iterable[object]) -> None:
        """Pass if any candidate (header, form field) is the token; else raise.

        Raises
        ------
        AccessDeniedError
            If none is. The message never echoes what was sent.
        """
        supplied = False
        for candidate in candidates:
            if candidate is None or candidate == "":
                continue
            supplied = True
            if self.matches(candidate):
                return
        if supplied:
            raise AccessDeniedError("wrong session token: nothing was changed")
        raise AccessDeniedError(
            "this action needs the session token printed by 'bowden serve' "
            f"(header {TOKEN_HEADER} or form field {TOKEN_FIELD}): nothing was changed"
        )

    def __repr__(self) -> str:  # never print the secret by accident (logs, tracebacks)
        return "SessionToken(<hidden>)"


class SecurityHeaders:
    """ASGI middleware adding :data:`SECURITY_HEADERS` to every HTTP response."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                present = {name.lower() for name, _ in message.get("headers", [])}
                headers = list(message.get("headers", []))
                headers.extend(h for h in SECURITY_HEADERS if h[0] not in present)
                message["headers"] = headers
            await send(message)

        await self.app(scope, receive, send_with_headers)


def same_origin(headers: dict[str, str]) -> bool:
    """Whether a WebSocket handshake comes from a page of this server (``Origin`` host == ``Host``).

    Browsers always send ``Origin`` on WebSocket handshakes; a page of another site that tries to
    open a socket to this server is refused (cross-site WebSocket hijacking). Non-browser clients
    that send no ``Origin`` are allowed: they could not be stopped by it anyway.
    """
    origin = headers.get("origin")
    if origin is None:
        return True
    host = headers.get("host", "")
    scheme, sep, rest = origin.partition("://")
    return bool(sep) and scheme in ("http", "https") and rest == host
