"""Starting, watching and stopping trials from the browser.

One trial at a time: :meth:`TrialManager.start` opens the suit, starts the recorder (study store)
and runs :class:`bowden.runtime.ControlLoop` in its own thread; the loop's rows go to the recorder
and, through a :class:`~bowden.web.live.SampleTap`, to the browsers. :meth:`TrialManager.stop`
asks the loop for a safe stop (torque ramps to zero, motor mode exited — the runtime's safe state)
and returns at once; the end of the trial is announced to the browsers when the loop is safe.

Everything that changes the manager's state runs in the server's event loop; the loop thread only
hands over rows and, at its end, its report.

A loop can also be run by someone else — ``bowden run --serve`` runs its trial in the main thread of
the command — and shown here: :meth:`TrialManager.attach` (called from that thread) makes it the
current trial and returns the non-blocking callback that feeds its rows to the browsers; the console's
stop button then asks that loop for its safe stop, and :meth:`TrialManager.detach` announces the end.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from bowden import __version__
from bowden.errors import BowdenError, ConflictError
from bowden.model import CompensationModel
from bowden.runtime import (
    ControlLoop,
    LoopConfig,
    LoopReport,
    LoopState,
    Recorder,
    Row,
    SafetyConfig,
    TrialInfo,
)
from bowden.runtime.realtime import RealtimeConfig
from bowden.runtime.slack import SlackTakeUp
from bowden.runtime.trial_sync import TrialSync
from bowden.web.live import ROLE_CONSOLE, ROLE_DISPLAY, LiveHub, SampleTap, Stamped, Thinning
from bowden.web.samples import FLAGS, STATE, TIME, console_samples, display_samples, fault_names
from bowden.web.suits import OpenSuit, SuitBackend
from bowden.web.trial_setup import TrialSetup, controller_for
from bowden.web.trial_signals import TrialSyncs, end_sync

_log = logging.getLogger(__name__)


@dataclass
class _Trial:
    setup: TrialSetup
    suit: OpenSuit
    loop: ControlLoop
    recorder: Recorder
    tap: SampleTap
    started_wall_s: float
    thread: threading.Thread | None = None
    flags_seen: int = 0
    fault_cycles: int = 0
    last_row: tuple[float | int, ...] | None = None
    stop_requested_by: str | None = None
    sync: TrialSync | None = None
    sync_notes: list[str] = field(default_factory=list)
    done: asyncio.Event = field(default_factory=asyncio.Event)


class TrialManager:
    """Runs trials for the web server.

    Parameters
    ----------
    backend
        Where the devices come from (simulated or real suit).
    model
        The compensation model of the suit (controller and tension estimate).
    model_metadata
        What each trial's metadata records of the model (its file, SHA-256 and coefficients).
    store_path
        The study store (SQLite) the recorder writes into.
    hub
        The browsers to inform.
    rate_hz
        Control rate.
    safety
        Watchdog thresholds of the trials' loops.
    slack
        The slack take-up that starts each trial (:class:`~bowden.runtime.slack.SlackTakeUp`), or None.
    sync
        The trigger line and LSL outlets each trial drives (:class:`TrialSyncs`), or None.
    display_rate_hz
        Rate of the samples sent to browsers (≥ the display's frame rate is enough).
    health_period_s
        How often the console gets loop health.
    """

    def __init__(
        self,
        *,
        backend: SuitBackend,
        model: CompensationModel,
        store_path: str | Path,
        model_metadata: Mapping[str, object] | None = None,
        hub: LiveHub,
        rate_hz: float = 500.0,
        safety: SafetyConfig | None = None,
        realtime: RealtimeConfig | None = None,
        slack: SlackTakeUp | None = None,
        sync: TrialSyncs | None = None,
        display_rate_hz: float = 100.0,
        health_period_s: float = 0.25,
    ) -> None:
        self.backend = backend
        self.model = model
        self.model_metadata = dict(model_metadata or {})
        self.store_path = Path(store_path)
        self.hub = hub
        self.rate_hz = rate_hz
        self.safety = safety if safety is not None else SafetyConfig()
        self.realtime = realtime
        self.slack = slack
        self.sync = sync
        self.health_period_s = health_period_s
        self._thinning = Thinning(display_rate_hz)
        self._trial: _Trial | None = None
        self._starting = False
        self._wake = asyncio.Event()
        self.last_result: dict[str, object] | None = None
        # Called in the event loop with each trial's end message, before the browsers get it.
        self.finished_listeners: list[Callable[[dict[str, object]], None]] = []
        self.trials_run = 0
        self.event_loop: asyncio.AbstractEventLoop | None = None  # the server's, set when it starts

    # --- operator actions (event loop) -----------------------------------------------------------
    @property
    def running(self) -> bool:
        return self._trial is not None or self._starting

    async def start(
        self, setup: TrialSetup, *, metadata: Mapping[str, object] | None = None
    ) -> dict[str, object]:
        """Start ``setup``'s trial; return its status once the loop runs.

        ``metadata`` is added to the trial's metadata (the session and plan step it runs).

        Raises
        ------
        ConflictError
            If a trial is running or starting (nothing else is changed).
        BowdenError
            If the suit or the store cannot be opened (nothing is left running).
        """
        if self.running:
            raise ConflictError("a trial is running: stop it before starting another")
        self._starting = True
        try:
            trial = await asyncio.to_thread(self._open, setup, asyncio.get_running_loop(), metadata or {})
        finally:
            self._starting = False
        self._trial = trial
        self._thinning.reset()
        self.trials_run += 1
        thread = threading.Thread(target=self._run, args=(trial,), name="bowden-control-loop", daemon=True)
        trial.thread = thread
        thread.start()
        self._announce(trial)
        return self.status(console=True)

    def _announce(self, trial: _Trial) -> None:
        setup = trial.setup
        _log.info("trial %s started: %s %s %s", trial.recorder.trial_id, setup.participant,
                  setup.condition, setup.speed)
        self.hub.publish(self._trial_message(trial, ROLE_DISPLAY), (ROLE_DISPLAY,))
        self.hub.publish(self._trial_message(trial, ROLE_CONSOLE), (ROLE_CONSOLE,))

    # --- a loop run elsewhere (bowden run --serve; called from that loop's thread) ---------------
    def attach(
        self,
        setup: TrialSetup,
        suit: OpenSuit,
        loop: ControlLoop,
        recorder: Recorder,
        *,
        timeout_s: float = 5.0,
    ) -> Callable[[Row], None]:
        """Show a loop that another thread runs as the current trial; call before ``loop.run()``.

        ``recorder`` is the run's own (started; the caller closes it before :meth:`detach`).
        Returns the callback the loop must call with each row (in addition to the recorder's): it
        only appends to a deque and at most wakes the server, so the loop never waits for the web.
        The console's stop calls ``loop.request_stop``, which the loop's safety path handles.

        Raises
        ------
        ConflictError
            If a trial is running or starting.
        BowdenError
            If the server is not running (or did not answer within ``timeout_s``).
        """
        future = asyncio.run_coroutine_threadsafe(
            self._adopt(setup, suit, loop, recorder), self._server_loop()
        )
        try:
            return future.result(timeout_s)
        except TimeoutError:
            future.cancel()
            raise BowdenError(f"the web server did not take the trial within {timeout_s:g} s") from None

    def detach(self, report: LoopReport | None, error: str | None = None, *, timeout_s: float = 5.0) -> None:
        """Announce the end of the attached trial (after its loop returned and its recorder closed).

        Returns once the browsers' messages are queued. Does nothing if the server is gone.
        """
        try:
            event_loop = self._server_loop()
        except BowdenError:
            return
        future = asyncio.run_coroutine_threadsafe(self._release(report, error), event_loop)
        with contextlib.suppress(TimeoutError):
            future.result(timeout_s)

    def _server_loop(self) -> asyncio.AbstractEventLoop:
        event_loop = self.event_loop
        if event_loop is None or event_loop.is_closed():
            raise BowdenError("the web server is not running")
        return event_loop

    async def _adopt(
        self, setup: TrialSetup, suit: OpenSuit, loop: ControlLoop, recorder: Recorder
    ) -> Callable[[Row], None]:
        if self.running:
            raise ConflictError("a trial is running: stop it before starting another")
        tap = SampleTap(asyncio.get_running_loop(), self._wake.set)
        trial = _Trial(setup, suit, loop, recorder, tap, time.time())
        self._trial = trial
        self._thinning.reset()
        self.trials_run += 1
        self._announce(trial)
        return tap.record

    async def _release(self, report: LoopReport | None, error: str | None) -> None:
        trial = self._trial
        if trial is not None and trial.thread is None:  # only an attached trial, never the manager's own
            self._finished(trial, report, error)

    def stop(self, reason: str = "operator stop") -> dict[str, object]:
        """Ask the running loop for a safe stop (returns at once).

        Raises
        ------
        ConflictError
            If no trial is running.
        """
        trial = self._trial
        if trial is None:
            raise ConflictError("no trial is running")
        trial.stop_requested_by = reason
        trial.loop.request_stop(reason)
        return self.status(console=True)

    async def wait(self, timeout_s: float | None = None) -> None:
        """Wait until the current trial (if any) has ended and been announced."""
        trial = self._trial
        if trial is not None:
            await asyncio.wait_for(trial.done.wait(), timeout_s)

    async def shutdown(self) -> None:
        """Stop a running trial safely and wait for it (server shutdown)."""
        if self._trial is not None:
            self.stop("server shutting down")
            await self.wait(10.0)

    # --- the trial thread ------------------------------------------------------------------------
    def _open(
        self, setup: TrialSetup, loop: asyncio.AbstractEventLoop, extra: Mapping[str, object]
    ) -> _Trial:
        controller = controller_for(setup, self.model)
        suit = self.backend.open(setup)
        try:
            info = TrialInfo(
                participant=setup.participant,
                condition=setup.condition,
                speed=setup.speed,
                support=setup.recorded_support,
                metadata={
                    "source": "bowden serve",
                    "backend": self.backend.name,
                    "suit": suit.description,
                    **suit.devices,
                    "rate_hz": self.rate_hz,
                    "bowden_version": __version__,
                    "compensation": getattr(controller, "compensation", None),
                    **self.model_metadata,
                    **{k: v for k, v in setup.to_json().items() if k not in ("participant", "condition")},
                    **extra,
                },
            )
            recorder = Recorder(self.store_path, info).start()
        except BaseException:
            suit.close()
            raise
        sync = self._start_sync(setup, suit, recorder, extra)
        tap = SampleTap(loop, self._wake.set)
        record_row, tap_row = recorder.record, tap.record
        sync_row = sync.row if sync is not None else None

        def record(row: Row) -> None:
            record_row(row)
            tap_row(row)
            if sync_row is not None:
                sync_row(row)

        control_loop = ControlLoop(
            controller=controller,
            motor=suit.motor,
            elevation_sensor=suit.elevation_sensor,
            clock=suit.clock,
            config=LoopConfig(rate_hz=self.rate_hz, duration_s=setup.duration_s, safety=self.safety,
                              slack=self.slack),
            tension_sensor=suit.tension_sensor,
            record=record,
            reference_elevation=setup.reference.elevation_rad,
            recorder_failure=lambda: recorder.failure,
            on_event=recorder.event,
            realtime=self.realtime,
        )
        return _Trial(setup, suit, control_loop, recorder, tap, time.time(), sync=sync)

    def _start_sync(
        self, setup: TrialSetup, suit: OpenSuit, recorder: Recorder, extra: Mapping[str, object]
    ) -> TrialSync | None:
        if self.sync is None:
            return None
        try:
            return self.sync.start(setup, recorder, extra)
        except BaseException as exc:
            with contextlib.suppress(BowdenError):
                recorder.close(stop_reason=f"error: the trial's sync signals could not start ({exc})")
            suit.close()
            raise

    def _run(self, trial: _Trial) -> None:
        report: LoopReport | None = None
        error: str | None = None
        try:
            report = trial.loop.run()
        except BowdenError as exc:
            error = str(exc)
        except Exception as exc:  # a bug must still end in a closed recording and a message
            _log.exception("the control loop failed")
            error = f"{type(exc).__name__}: {exc}"
        if trial.sync is not None and self.sync is not None:  # trigger low before the recording closes
            last_s = float(trial.last_row[TIME]) if trial.last_row is not None else 0.0
            trial.sync_notes = end_sync(self.sync, trial.sync, report, error=error, last_time_s=last_s)
            for note in trial.sync_notes:
                _log.info("trial %s %s", trial.recorder.trial_id, note)
        try:
            trial.suit.close()
        except Exception:
            _log.exception("closing the suit failed")
        recorder = trial.recorder
        if report is not None:
            kind = "safe_stop" if report.clean else "fault"
            recorder.event(report.stop_time_s, kind, report.reason)
        reason = report.reason if report is not None else f"error: {error}"
        try:
            recorder.close(stop_reason=reason)
        except BowdenError as exc:
            error = f"{error}; {exc}" if error else str(exc)
        loop = trial.tap.loop
        # RuntimeError: the server is gone; the recording is closed, nothing is left to tell.
        with contextlib.suppress(RuntimeError):
            loop.call_soon_threadsafe(self._finished, trial, report, error)

    def _finished(self, trial: _Trial, report: LoopReport | None, error: str | None) -> None:
        self._flush()
        clean = bool(report is not None and report.clean and error is None)
        # Completed: the whole reference ran (no stop asked for, no fault, no error).
        completed = clean and trial.stop_requested_by is None
        result: dict[str, object] = {
            "type": "stopped",
            "trial_id": trial.recorder.trial_id,
            "reason": report.reason if report is not None else f"error: {error}",
            "clean": clean,
            "completed": completed,
            "faults": fault_names(int(report.fault)) if report is not None else [],
            "error": error,
            "committed_rows": trial.recorder.stats.committed_rows,
            "sync": trial.sync_notes,
        }
        if report is not None:
            result.update(
                cycles=report.cycles,
                timing=report.timing.describe(),
                deadline_misses=report.timing.deadline_misses,
                motor_disabled=report.motor_disabled,
                safe_time_s=report.safe_time_s,
                health=report.describe_health(),
            )
        self.last_result = result
        self._trial = None
        for listener in self.finished_listeners:
            try:
                listener(result)
            except Exception:  # a listener's failure must not leave the trial unannounced
                _log.exception("a trial-end listener failed")
        self.hub.publish(result, (ROLE_CONSOLE,))
        # The display says whether the reference ran to its end or was stopped (no ids, no reasons).
        self.hub.publish({"type": "stopped", "completed": completed}, (ROLE_DISPLAY,))
        trial.done.set()

    # --- live data (event loop) ------------------------------------------------------------------
    async def pump(self) -> None:
        """Forward rows to the browsers as they come, and loop health periodically (runs forever)."""
        next_health = time.monotonic()
        while True:
            timeout = max(0.0, next_health - time.monotonic())
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._wake.wait(), timeout)
            self._wake.clear()
            self._flush()
            if time.monotonic() >= next_health:
                next_health = time.monotonic() + self.health_period_s
                if self._trial is not None:
                    self.hub.publish(self.health(), (ROLE_CONSOLE,))

    def _flush(self) -> None:
        trial = self._trial
        if trial is None:
            return
        rows = trial.tap.drain()
        if not rows:
            return
        for _, _, row in rows:
            flags = int(row[FLAGS])
            if flags:
                trial.flags_seen |= flags
                trial.fault_cycles += 1
        trial.last_row = rows[-1][2]
        kept = self._thinning.keep(rows, TIME)
        if kept:
            self._publish_samples(kept)

    def _publish_samples(self, kept: list[Stamped]) -> None:
        display = display_samples(kept)
        self.hub.publish(display, (ROLE_DISPLAY,))
        if self.hub.count(ROLE_CONSOLE):  # the console's extra columns only when someone watches
            self.hub.publish(console_samples(display, kept, self.model), (ROLE_CONSOLE,))

    # --- status ----------------------------------------------------------------------------------
    def health(self) -> dict[str, object]:
        """Loop health of the running trial (console)."""
        trial = self._trial
        if trial is None:
            return {"type": "health", "state": "idle"}
        timing = trial.loop.timing
        row = trial.last_row
        state = LoopState(int(row[STATE])).name.lower() if row is not None else "starting"
        latest_flags = int(row[FLAGS]) if row is not None else 0
        return {
            "type": "health",
            "state": state,
            "trial_time_s": float(row[TIME]) if row is not None else 0.0,
            "cycles": timing.cycles,
            "deadline_misses": timing.deadline_misses,
            "skipped_cycles": timing.skipped_cycles,
            "worst_lateness_ms": 1e3 * timing.worst_lateness_s,
            "fault_flags": latest_flags,
            "faults": fault_names(latest_flags),
            "faults_seen": fault_names(trial.flags_seen),
            "fault_cycles": trial.fault_cycles,
            "committed_rows": trial.recorder.stats.committed_rows,
            "stop_requested": trial.stop_requested_by,
            **trial.suit.health(),
        }

    def _trial_message(self, trial: _Trial, role: str) -> dict[str, object]:
        message: dict[str, object] = {
            "type": "trial",
            "state": "running",
            "reference": trial.setup.reference.to_json(),
        }
        if role == ROLE_CONSOLE:  # the display never gets the participant's id
            message.update(
                setup=trial.setup.to_json(),
                trial_id=trial.recorder.trial_id,
                suit=trial.suit.description,
            )
        return message

    def status(self, *, console: bool) -> dict[str, object]:
        """What a newly connected browser needs to know (``console``: with ids and last result)."""
        trial = self._trial
        role = ROLE_CONSOLE if console else ROLE_DISPLAY
        status: dict[str, object] = {"type": "trial", "state": "idle"}
        if trial is not None:
            status = self._trial_message(trial, role)
        if console:
            status["last_result"] = self.last_result
            status["backend"] = self.backend.name
        return status
