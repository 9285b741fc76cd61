"""Synchronisation with an EMG amplifier, shared by ``bowden run`` and ``bowden serve``.

``--trigger SPEC`` (a digital line, :mod:`bowden.hardware.trigger`) and ``--lsl`` (Lab Streaming Layer
outlets, :mod:`bowden.runtime.lsl_outlets`) are opened once and stay open for as long as the command
runs: ``run``'s one trial, or every trial ``serve``'s console starts (LabRecorder keeps the same two
streams over a whole session). Each trial gets its own :class:`~bowden.runtime.trial_sync.TrialSync`
on them (:meth:`SyncOutputs.trial`): the session marker, the trigger pulse over the trial, the
repetition markers, the loop's samples and the two sync events in the trial's record.
:func:`trigger_report` says afterwards how long each edge took to send, and warns when that is more
than ``bowden emg import`` accepts.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass

from bowden.errors import ParameterError
from bowden.hardware.trigger import TriggerLine, open_trigger
from bowden.runtime.lsl_outlets import LslOutlets
from bowden.runtime.trial_sync import TrialSync
from bowden.web.reference import TrialReference

EventSink = Callable[[float, str, str], None]


def add_sync_arguments(parser: argparse.ArgumentParser, *, trials: str) -> None:
    """``--lsl``, ``--lsl-wait`` and ``--trigger``; ``trials`` says which trials they sync ("the trial")."""
    sync = parser.add_argument_group("synchronisation with an EMG amplifier (see bowden emg import)")
    sync.add_argument(
        "--lsl",
        action="store_true",
        help=f"publish Lab Streaming Layer streams while {trials} runs: bowden's markers and the loop's "
        "signals (needs the lsl extra)",
    )
    sync.add_argument(
        "--lsl-wait",
        type=float,
        default=0.0,
        metavar="S",
        help=f"with --lsl: wait up to S seconds for a recorder (LabRecorder) to connect before {trials}",
    )
    sync.add_argument(
        "--trigger",
        metavar="SPEC",
        help=f"raise a digital line at the start of {trials}, lower it at its end: gpio:CHIP:LINE (e.g. "
        "gpio:/dev/gpiochip1:28, BeagleBone P9_12; needs the gpio extra) or 'command:PROGRAM ARGS' "
        "with {level} for 1/0",
    )


def repetition_onsets_s(reference: TrialReference) -> list[float]:
    """Loop times at which ``reference`` starts each repetition (a marker each), s."""
    return [reference.start_s + k * reference.cycle.period_s for k in range(reference.repetitions)]


@dataclass
class SyncOutputs:
    """The open trigger line and LSL outlets; :meth:`trial` makes each trial's sync on them.

    Parameters
    ----------
    trigger
        The trigger line (``--trigger``), or None.
    lsl
        The outlets (``--lsl``), or None.
    lsl_wait_s
        How long each trial waits for a recorder to connect (``--lsl-wait``), s.
    say
        Where the notes go (one line each).
    """

    trigger: TriggerLine | None
    lsl: LslOutlets | None
    lsl_wait_s: float
    say: Callable[[str], None]

    def trial(
        self,
        *,
        trial_id: int | None,
        on_event: EventSink | None,
        reference: TrialReference,
        session: Mapping[str, object],
    ) -> TrialSync:
        """One trial's sync (sends the session marker now); call ``finish`` on it after the loop."""
        lsl = self.lsl
        if lsl is not None and self.lsl_wait_s > 0.0 and not lsl.wait_for_consumers(self.lsl_wait_s):
            self.say(f"LSL: no recorder connected within {self.lsl_wait_s:g} s; starting anyway")
        return TrialSync(
            trial_id=trial_id,
            trigger=self.trigger,
            lsl=lsl,
            on_event=on_event,
            repetition_onsets_s=repetition_onsets_s(reference),
            session=dict(session),
        )

    def ended(self, sync: TrialSync) -> list[str]:
        """What to say after a trial's ``finish``: a failed trigger, or how long its edges took."""
        if sync.error is not None:
            return [f"sync: the trigger failed ({sync.error}); this trial has no sync events"]
        if self.trigger is None:
            return []
        return trigger_report(sync.edge_uncertainties_s)


def open_sync_outputs(
    args: argparse.Namespace, stack: ExitStack, *, rate_hz: float, say: Callable[[str], None]
) -> SyncOutputs | None:
    """The trigger line and outlets ``--trigger``/``--lsl`` ask for (closed by ``stack``), or None.

    Raises
    ------
    ParameterError, MissingExtraError, HardwareError
        For a trigger spec that is wrong or a line that cannot be opened, or a missing extra.
    """
    if not (math.isfinite(args.lsl_wait) and args.lsl_wait >= 0.0):
        raise ParameterError(f"--lsl-wait must be a number of seconds >= 0, got {args.lsl_wait:g}")
    if args.lsl_wait > 0.0 and not args.lsl:
        raise ParameterError("--lsl-wait waits for a recorder of the --lsl streams: add --lsl or drop it")
    if not args.lsl and args.trigger is None:
        return None
    trigger = open_trigger(args.trigger) if args.trigger is not None else None
    if trigger is not None:
        stack.callback(trigger.close)
    lsl = None
    if args.lsl:
        lsl = LslOutlets(rate_hz=rate_hz)
        stack.callback(lsl.close)
        say(f"LSL: publishing {lsl.marker_source_id} and {lsl.loop_source_id}")
    return SyncOutputs(trigger=trigger, lsl=lsl, lsl_wait_s=args.lsl_wait, say=say)


def trigger_report(uncertainties_s: dict[str, float]) -> list[str]:
    """How long each trigger edge took to send (the edge lies within), and one warning line when that
    exceeds the sync residual ``bowden emg import`` accepts."""
    if not uncertainties_s:
        return []
    from bowden.analysis.emg.sync import RESIDUAL_TOLERANCE_S

    edges = ", ".join(f"{edge} within {1e3 * spread:.3f} ms" for edge, spread in uncertainties_s.items())
    lines = [f"sync: trigger edges sent: {edges}"]
    worst = max(uncertainties_s.values())
    if worst > RESIDUAL_TOLERANCE_S:
        lines.append(
            f"sync: warning: a trigger edge took {1e3 * worst:.0f} ms to send, beyond the "
            f"{1e3 * RESIDUAL_TOLERANCE_S:g} ms residual bowden emg import accepts: the EMG aligns no better "
            "than that; drive the line from a GPIO output (--trigger gpio:CHIP:LINE, microseconds) instead"
        )
    return lines
