"""`bowden serve --lsl --trigger command:...`: every console trial publishes its markers and loop samples
and pulses the trigger line, as `bowden run` does, on outlets and a line that stay open across trials.

The server is the real command in its own process; the test is the recorder (LabRecorder's part): its
pylsl inlets resolve the streams on this machine only (``ResolveScope = machine``, via $LSLAPICFG,
set before liblsl reads its configuration). The trigger is a real command that logs each level it is
given with the monotonic clock, so the sync events in the store can be checked against the moments the
line changed.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).parent
# liblsl reads its configuration once per process, at its first use: set it before any test runs.
os.environ["LSLAPICFG"] = str(HERE / "lsl_machine.cfg")
pylsl = pytest.importorskip("pylsl")
httpx = pytest.importorskip("httpx2")

from bowden.runtime.sync_events import SYNC_KIND, SyncEvent  # noqa: E402
from bowden.store.study_store import StudyStore  # noqa: E402

TRIGGER_LOG = HERE.parent / "runtime" / "trigger_log.py"


class Served:
    """``bowden serve`` in a child process: its address, token, and everything it printed."""

    def __init__(self, process: subprocess.Popen[str]) -> None:
        self.process = process
        self.lines: list[str] = []
        self._changed = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            with self._changed:
                self.lines.append(line.rstrip("\n"))
                self._changed.notify_all()

    def wait_for(self, pattern: str, timeout_s: float = 60.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while True:
                found = next((m for line in self.lines if (m := re.search(pattern, line))), None)
                if found is not None:
                    return found
                left = deadline - time.monotonic()
                if left <= 0.0 or (self.process.poll() is not None and not self._changed.wait(0.5)):
                    raise AssertionError(f"never printed {pattern!r}; printed:\n" + "\n".join(self.lines))
                self._changed.wait(min(0.5, left))


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[Served, Path, Path]]:
    store, levels = tmp_path / "study.db", tmp_path / "levels.txt"
    trigger = f"command:{sys.executable} {TRIGGER_LOG} {levels} {{level}}"
    argv = [sys.executable, "-m", "bowden", "serve", "--store", str(store), "--port", "0", "--lsl",
            "--lsl-wait", "60", "--trigger", trigger, "--rate-hz", "250"]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(argv, env=env, cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    try:
        yield Served(process), store, levels
    finally:
        process.terminate()  # SIGTERM: uvicorn stops the running trial safely, then exits
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()


def inlet(name: str) -> pylsl.StreamInlet:
    found = pylsl.resolve_byprop("name", name, minimum=1, timeout=60.0)
    assert found, f"stream {name!r} not found on this machine"
    stream = pylsl.StreamInlet(found[0], max_buflen=360)
    stream.open_stream(timeout=30.0)
    return stream


def pull(markers: pylsl.StreamInlet, loop: pylsl.StreamInlet, trials: int) -> tuple[list, list[float]]:
    """Markers (stamp, fields) and loop times until ``trials`` trial-end markers came and 0.5 s passed
    without data (the trials have ended: what is left is in liblsl's buffers or on loopback)."""
    got: list[tuple[float, dict[str, object]]] = []
    times: list[float] = []
    last = time.monotonic()
    deadline = last + 120.0
    while time.monotonic() < deadline:
        chunk, _ = loop.pull_chunk(timeout=0.05, max_samples=4000)
        if chunk:
            times.extend(sample[0] for sample in chunk)
            last = time.monotonic()
        while (sample := markers.pull_sample(timeout=0.0))[0] is not None:
            got.append((sample[1], json.loads(sample[0][0])))
            last = time.monotonic()
        ended = sum(1 for _, m in got if m["event"] == "trial_end")
        if ended >= trials and time.monotonic() - last > 0.5:
            return got, times
    raise AssertionError(f"{trials} trial(s) never ended on the marker stream: {got}")


def run_trial(http: httpx.Client, token: str, participant: str, repetitions: int) -> int:
    body = {"participant": participant, "condition": "support_50", "speed": "V3", "repetitions": repetitions,
            "lead_in_s": 0.3, "height_m": 1.70, "mass_kg": 63.0, "sex": "female"}
    started = http.post("/api/trial/start", headers={"X-Bowden-Token": token}, json=body)
    assert started.status_code == 201, started.text
    trial_id = int(started.json()["trial_id"])
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        status = http.get("/api/console/status", headers={"X-Bowden-Token": token}).json()
        last = status.get("last_result")
        if status["state"] == "idle" and last is not None and last["trial_id"] == trial_id:
            assert last["clean"] and last["completed"], last
            return trial_id
        time.sleep(0.1)
    raise AssertionError(f"trial {trial_id} did not end")


def test_console_trials_publish_lsl_and_pulse_the_trigger_like_run(served) -> None:
    server, store, levels = served
    url = server.wait_for(r"bowden serve: (http://\S+)").group(1)
    token = server.wait_for(r"session token:\s+(\S+)").group(1)
    server.wait_for(r"LSL: publishing bowden-markers-\S+ and bowden-loop-\S+")
    markers, loop = inlet("bowden markers"), inlet("bowden loop")
    assert loop.info().channel_count() == 6 and loop.info().nominal_srate() == 250.0
    with httpx.Client(base_url=url, timeout=30.0) as http:
        # Two repetitions, then one: the onsets are numbered within each trial.
        trials = [run_trial(http, token, "P01", 2), run_trial(http, token, "P02", 1)]
    got, loop_times = pull(markers, loop, trials=2)
    lines = [line.split() for line in levels.read_text().splitlines()]
    assert [level for level, _ in lines] == ["1", "0", "1", "0"]  # one pulse a trial, on one line
    with StudyStore(store) as opened:
        for k, trial_id in enumerate(trials):
            samples = opened.trial_samples(trial_id)
            events = opened.read_sql(
                "SELECT time_s, message FROM events WHERE trial_id = ? AND kind = ?", (trial_id, SYNC_KIND)
            )
            mine = [(stamp, m) for stamp, m in got if m.get("trial") == trial_id]
            # Every marker of the trial, as bowden run sends them, with the console's session fields.
            assert [m["event"] for _, m in mine] == [
                "session", "trial_start", *["repetition"] * (2 - k), "safe_stop", "trial_end"]
            session = mine[0][1]
            assert session["participant"] == f"P0{k + 1}" and session["condition"] == "support_50"
            assert session["speed"] == "V3" and session["store"] == "study.db"
            assert [m["repetition"] for _, m in mine if m["event"] == "repetition"] == [1, 2][:2 - k]
            assert mine[2][1]["time_s"] == pytest.approx(0.3)  # the first onset: after the lead-in
            # The loop stream: the trial's cycles, each once.
            recorded = samples["time_s"].to_numpy()
            fraction = np.isin(recorded, np.asarray(loop_times)).mean()
            assert fraction >= 0.999, f"{100 * fraction:.2f} % of the recorded cycles were received"
            # The sync events: the two edges, on the host clock when the trigger command ran.
            edges = [SyncEvent.from_event(t, m) for t, m in events.itertuples(index=False)]
            sync = {e.edge: e for e in edges}
            assert set(sync) == {"start", "end"}
            for (_, written), edge in zip(lines[2 * k:2 * k + 2], ("start", "end"), strict=True):
                event = sync[edge]
                assert event.trigger is not None and event.trigger.startswith("command")
                half = 0.5 * event.uncertainty_s
                assert event.host_time_s - half <= float(written) <= event.host_time_s + half
    # Each trial's end says how long its edges took to send (a Python command: tens of ms, warned).
    server.wait_for(r"trial \d+ sync: trigger edges sent: start within [\d.]+ ms, end within [\d.]+ ms")
    server.wait_for(r"sync: warning: a trigger edge took \d+ ms to send")
