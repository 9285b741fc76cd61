"""``bowden bench run``'s safe stop is a KeyboardInterrupt handler: SIGINT and SIGTERM must raise it
whatever the process inherited (a script's background job ignores SIGINT, POSIX; SIGTERM's default
ends the process without the safe stop)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bowden.runtime.signals import interrupt_on_signals


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_each_signal_interrupts_inside_the_block_and_the_inherited_disposition_returns(signum):
    before = signal.signal(signum, signal.SIG_IGN)  # as a background job inherits SIGINT
    try:
        with pytest.raises(KeyboardInterrupt), interrupt_on_signals():
            os.kill(os.getpid(), signum)
            time.sleep(5.0)  # the handler runs here; never reached to the end
        assert signal.getsignal(signum) is signal.SIG_IGN
    finally:
        signal.signal(signum, before)


def test_a_bench_run_started_in_the_background_stops_safely_on_sigterm(tmp_path: Path) -> None:
    # Before, SIGTERM ended `bowden bench run` at once: no safe stop, no "interrupted" and exit -15.
    output = tmp_path / "bench.csv"
    command = [sys.executable, "-m", "bowden", "bench", "run", "--backend", "sim", "-o", str(output),
               "--speeds", "1", "--loads", "1", "--repetitions", "2", "--high-deg", "50"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert process.stderr is not None
    said = []
    for line in process.stderr:  # the first stroke recorded: the run is under way
        said.append(line)
        if line.startswith("stroke 1 of 4"):
            break
    process.send_signal(signal.SIGTERM)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 130, "".join(said) + err
    assert "interrupted; both motors are out of motor mode" in err, err
