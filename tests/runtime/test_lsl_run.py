"""`bowden run --lsl --trigger command:...` on the simulated suit, received by pylsl in another process.

Both processes find each other through liblsl's own discovery, kept on this machine by an
``lsl_api.cfg`` with ``ResolveScope = machine`` (via $LSLAPICFG). The trigger is a real command that
logs each level it is given with the monotonic clock, so the sync events in the store can be checked
against the moments the line changed.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("pylsl")

from bowden.runtime.sync_events import SYNC_KIND, SyncEvent
from bowden.store.study_store import StudyStore

HERE = Path(__file__).parent


def lsl_config(directory: Path) -> Path:
    config = directory / "lsl_api.cfg"
    config.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n")
    return config


def test_a_sim_trial_publishes_every_marker_and_its_loop_samples(tmp_path: Path) -> None:
    env = {**os.environ, "LSLAPICFG": str(lsl_config(tmp_path))}
    received = tmp_path / "received.json"
    receiver = subprocess.Popen(
        [sys.executable, str(HERE / "lsl_receiver.py"), str(received)], env=env, cwd=tmp_path
    )
    store, levels = tmp_path / "study.db", tmp_path / "levels.txt"
    trigger = f"command:{sys.executable} {HERE / 'trigger_log.py'} {levels} {{level}}"
    try:
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "bowden",
                "run",
                "--backend",
                "sim",
                "--duration",
                "4",  # two V3 repetitions (5/3 s each) after the lead-in
                "--speed",
                "V3",
                "--lead-in",
                "0.5",
                "--condition",
                "support_50",
                "--record",
                str(store),
                "--lsl",
                "--lsl-wait",
                "120",
                "--trigger",
                trigger,
            ],
            env=env,
            cwd=tmp_path,
            capture_output=True,
            text=True,
            timeout=240,
        )
        assert run.returncode == 0, run.stderr
        assert receiver.wait(timeout=120) == 0
    finally:
        if receiver.poll() is None:
            receiver.kill()
    got = json.loads(received.read_text())
    with StudyStore(store) as opened:
        (trial,) = opened.completed_trials()
        samples = opened.trial_samples(trial.trial_id)
        events = opened.read_sql("SELECT time_s, kind, message FROM events WHERE kind = ?", (SYNC_KIND,))
    # The loop stream: one sample per recorded cycle, stamped on the host clock.
    assert got["loop_channels"] == 6 and got["loop_rate_hz"] == 500.0
    assert got["marker_source_id"].startswith("bowden-markers-")
    recorded = samples["time_s"].to_numpy()
    loop_times = np.asarray(got["loop_times_s"])
    fraction = np.isin(recorded, loop_times).mean()
    print(f"LSL loop samples received: {len(loop_times)} of {len(recorded)} cycles ({100 * fraction:.3f} %)")
    assert fraction >= 0.999
    # Every marker: the session, the trial's start and end, each repetition onset, the safe stop.
    markers = [(stamp, json.loads(text)) for stamp, text in got["markers"]]
    kinds = [m["event"] for _, m in markers]
    reference = samples["reference_elevation_rad"].to_numpy()
    low = reference.min()
    # Onsets: the first departure from the low elevation, then each return to it (a local minimum).
    first = int(np.flatnonzero(reference > low + 1e-9)[0])
    inner = np.arange(1, len(reference) - 1)
    minima = inner[(reference[inner] < reference[inner - 1]) & (reference[inner] <= reference[inner + 1])]
    ends = minima[minima > first]
    onsets = np.concatenate([[first], ends[reference[ends + 1] > reference[ends]]])
    assert len(onsets) >= 2
    assert kinds == ["session", "trial_start", *["repetition"] * len(onsets), "safe_stop", "trial_end"]
    assert all(m.get("trial") == trial.trial_id for _, m in markers)
    numbers = [m["repetition"] for _, m in markers if m["event"] == "repetition"]
    assert numbers == list(range(1, len(onsets) + 1))
    repetition_times = [m["time_s"] for _, m in markers if m["event"] == "repetition"]
    # Each onset marker names the reference's onset: within the one cycle the recording resolves.
    np.testing.assert_allclose(repetition_times, recorded[onsets], atol=4.5e-3)
    # The sync events: on the host clock when the trigger command ran, and the markers' stamps.
    sync = {e.edge: e for e in (SyncEvent.from_event(t, m) for t, _, m in events.itertuples(index=False))}
    assert set(sync) == {"start", "end"}
    lines = [line.split() for line in levels.read_text().splitlines()]
    assert [level for level, _ in lines] == ["1", "0"]
    for (_, written), edge in zip(lines, ("start", "end"), strict=True):
        event = sync[edge]
        assert event.trigger is not None and event.trigger.startswith("command")
        half = 0.5 * event.uncertainty_s
        assert event.host_time_s - half <= float(written) <= event.host_time_s + half
    stamps = {m["event"]: stamp for stamp, m in markers}
    assert math.isclose(stamps["trial_start"], sync["start"].host_time_s, abs_tol=1e-3)
    assert math.isclose(stamps["trial_end"], sync["end"].host_time_s, abs_tol=1e-3)
    # Loop time zero is where both events put it. The loop stream's stamps use the same estimate of
    # it, refined downwards as cycles run (the least of host time − loop time so far): the early stamps
    # may carry a busy host's scheduling delay, the refined one is the events' zero.
    assert math.isclose(sync["start"].zero_host_time_s, sync["end"].zero_host_time_s, abs_tol=1e-9)
    offsets = np.asarray(got["stamps"]) - np.asarray(got["loop_times_s"])
    assert np.all(np.diff(offsets) <= 1e-6)  # never later than before
    assert math.isclose(float(offsets.min()), sync["start"].zero_host_time_s, abs_tol=1e-3)
