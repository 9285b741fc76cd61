"""Peers that answer in wall time start on a compiled plant (the CI failure of the every-check test).

On a fresh checkout the plant's kernels compile on their first call, tens of seconds; the pre-flight's
motor has 0.1 s to answer. The check runs in a fresh interpreter, where nothing is compiled or loaded
yet, and asks numba whether the plant's step exists before and after the pre-flight's rig is entered,
before any device has been asked anything (the rig warms a throwaway suit: ``warm_up_suit``).
"""

from __future__ import annotations

import subprocess
import sys

SCRIPT = """
from bowden.sim import _kernels as k
print(len(k.integrate.signatures))
from bowden.hardware.motors import motor_model
from bowden.sim.peers.check_rig import simulated_rig
with simulated_rig(motor_model("AK60-6").limits(None)):
    print(len(k.integrate.signatures))
"""


def test_the_plant_is_compiled_before_a_device_is_asked() -> None:
    result = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=300,
                            check=False)
    assert result.returncode == 0, result.stderr
    before, inside = (int(line) for line in result.stdout.split())
    assert before == 0  # importing compiles nothing: entering the rig is what does
    assert inside >= 1
