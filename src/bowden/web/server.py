"""Running the web application: configuration, the uvicorn server, and a background-thread variant.

The listening socket is bound before the server starts, so the printed addresses carry the real port
(also with ``port=0``), and a port already in use is a clear error instead of a traceback.
"""

from __future__ import annotations

import logging
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import Final, Self

import uvicorn
from starlette.applications import Starlette

from bowden.errors import BowdenError, ParameterError
from bowden.model import CompensationModel
from bowden.model.model_record import model_record
from bowden.protocol.session_plan import StudyProtocol
from bowden.runtime import SafetyConfig
from bowden.runtime.realtime import RealtimeConfig
from bowden.runtime.slack import SlackTakeUp
from bowden.web.app import create_app
from bowden.web.live import LiveHub
from bowden.web.preflight_routes import Preflight
from bowden.web.questionnaire_store import QuestionnaireStore
from bowden.web.security import SessionToken
from bowden.web.session_desk import SessionDesk
from bowden.web.suits import SimulatedBackend, SuitBackend
from bowden.web.trial_signals import TrialSyncs
from bowden.web.trials import TrialManager

_log = logging.getLogger(__name__)
LOOPBACK_HOSTS: Final = ("127.0.0.1", "localhost", "::1")


@dataclass(frozen=True, kw_only=True)
class ServeConfig:
    """What ``bowden serve`` runs.

    Parameters
    ----------
    store_path
        The study store (SQLite): trials, samples and questionnaires.
    model
        The suit's compensation model.
    model_file
        The ``model.json`` it was loaded from (None: built in memory); each trial records its
        SHA-256 and the model's coefficients (:mod:`bowden.model.model_record`).
    backend
        Where trials get their devices (default: the simulated suit in real time).
    host, port
        Where to listen; loopback unless told otherwise (the token is the only guard beyond it).
    rate_hz
        Control-loop rate.
    safety
        Watchdog thresholds of the trials' loops.
    realtime
        Real-time settings of the trials' loop thread (None: leave its scheduling alone).
    slack
        The slack take-up that starts each trial (None: assist at once).
    token
        The session token; None draws a fresh one.
    protocol
        The protocol of the session plans (default: the paper's).
    sync
        The trigger line and LSL outlets each console trial drives (``--trigger``, ``--lsl``), or None.
    preflight
        The checks of ``bowden check`` the console runs before a session (returns its ``--json``
        report), or None.
    """

    store_path: Path
    model: CompensationModel
    model_file: Path | None = None
    backend: SuitBackend = field(default_factory=SimulatedBackend)
    host: str = "127.0.0.1"
    port: int = 8765
    rate_hz: float = 500.0
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    realtime: RealtimeConfig | None = None
    slack: SlackTakeUp | None = None
    token: str | None = None
    protocol: StudyProtocol = field(default_factory=StudyProtocol)
    sync: TrialSyncs | None = None
    preflight: Preflight | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.port, int) and 0 <= self.port <= 65535):
            raise ParameterError(f"ServeConfig.port must be 0–65535, got {self.port!r}")
        if not self.host:
            raise ParameterError("ServeConfig.host must not be empty")

    @property
    def allowed_hosts(self) -> list[str]:
        """Host names the server answers to: loopback names, plus the bound host; any if all."""
        if self.host in ("0.0.0.0", "::", ""):
            return ["*"]
        hosts = ["127.0.0.1", "localhost", "::1", "[::1]"]
        if self.host not in hosts:
            hosts.append(self.host)
        return hosts


@dataclass
class WebServer:
    """The application and what it holds, before it listens."""

    config: ServeConfig
    app: Starlette
    token: SessionToken
    manager: TrialManager
    questionnaires: QuestionnaireStore
    desk: SessionDesk


def build_server(config: ServeConfig) -> WebServer:
    """Create the study store tables, the trial manager and the application."""
    token = SessionToken(config.token)
    questionnaires = QuestionnaireStore(config.store_path)
    manager = TrialManager(
        backend=config.backend,
        model=config.model,
        model_metadata={"model": str(config.model_file) if config.model_file else "built in (no model.json)",
                        **model_record(config.model, config.model_file)},
        store_path=config.store_path,
        hub=LiveHub(),
        rate_hz=config.rate_hz,
        safety=config.safety,
        realtime=config.realtime,
        slack=config.slack,
        sync=config.sync,
    )
    desk = SessionDesk(config.store_path, manager, config.protocol)
    app = create_app(
        manager=manager, questionnaires=questionnaires, desk=desk, token=token,
        allowed_hosts=config.allowed_hosts, preflight=config.preflight,
    )
    return WebServer(config, app, token, manager, questionnaires, desk)


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host:port`` (port 0: any free port).

    Raises
    ------
    BowdenError
        If the address cannot be bound (in use, not an address of this machine).
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
        sock.listen(64)
    except OSError as error:
        sock.close()
        raise BowdenError(
            f"cannot listen on {host}:{port}: {error.strerror or error} (choose another --port or --host; "
            "--port 0 picks a free port)"
        ) from None
    sock.setblocking(False)
    return sock


def base_url(sock: socket.socket) -> str:
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    if host in ("0.0.0.0", "::"):
        shown = "127.0.0.1"
    return f"http://{shown}:{port}"


def addresses(url: str, token: SessionToken) -> dict[str, str]:
    """The pages to open; operator pages carry the token in the fragment (never sent to the server)."""
    return {
        "participant display": f"{url}/display",
        "operator console": f"{url}/console#token={token.value}",
        "questionnaires": f"{url}/questionnaire#token={token.value}",
        "session token": token.value,
    }


def announcement(
    config: ServeConfig, url: str, token: SessionToken, *, title: str = "bowden serve"
) -> list[str]:
    """The lines printed at start: where the server listens, the pages, and the session token."""
    lines = [f"{title}: {url}  (store {config.store_path}, backend {config.backend.name})"]
    if config.host not in LOOPBACK_HOSTS:
        lines.append("warning: listening beyond this machine; anyone on the network can watch the display")
    lines.extend(f"  {name + ':':22s}{address}" for name, address in addresses(url, token).items())
    return lines


def _uvicorn(app: Starlette) -> uvicorn.Server:
    config = uvicorn.Config(app, log_level="warning", lifespan="on", ws="websockets-sansio", access_log=False)
    return uvicorn.Server(config)


def serve(config: ServeConfig, *, announce: Callable[[str], None] = print) -> None:
    """Listen until interrupted (Ctrl-C stops a running trial safely first)."""
    server = build_server(config)
    sock = bind(config.host, config.port)
    for line in announcement(config, base_url(sock), server.token):
        announce(line)
    _uvicorn(server.app).run(sockets=[sock])


class ServerThread:
    """The server in a background thread (tests, benchmarks, ``bowden run --serve``).

    Use as a context manager; ``url`` is set once it listens.
    """

    def __init__(self, config: ServeConfig) -> None:
        self.web = build_server(config)
        self._sock = bind(config.host, config.port)
        self.url = base_url(self._sock)
        self._server = _uvicorn(self.web.app)
        self._thread = threading.Thread(
            target=self._server.run, kwargs={"sockets": [self._sock]}, name="bowden-web", daemon=True
        )

    def announcement(self, *, title: str = "bowden serve") -> list[str]:
        """The addresses and the session token, as :func:`serve` prints them."""
        return announcement(self.web.config, self.url, self.web.token, title=title)

    def __enter__(self) -> Self:
        self._thread.start()
        deadline = time.monotonic() + 10.0
        while not self._server.started:
            if not self._thread.is_alive() or time.monotonic() > deadline:
                raise BowdenError("the web server did not start")
            time.sleep(0.01)
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._server.should_exit = True
        self._thread.join(15.0)
        self._sock.close()
