"""Peers that answer in wall time start on a compiled plant (the CI failure of the every-check test).

On a fresh checkout the plant's kernels compile on their first call, tens of seconds; the pre-flight's
motor has 0.1 s to answer. Each case runs in a fresh interpreter, where nothing is compiled or loaded
yet, and asks numba whether the plant's step exists before any device has been asked anything.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

CASES = {
    "the pre-flight's rig": """
        from bowden.hardware.motors import motor_model
        from bowden.sim.peers.check_rig import simulated_rig
        with simulated_rig(motor_model("AK60-6").limits(None)):
            print(len(k.integrate.signatures))
    """,
    "a throwaway suit": """
        from bowden.sim.arm import PrescribedArm
        from bowden.sim.peers.warm_up import warm_up_suit
        warm_up_suit(PrescribedArm.hold(0.0))
        print(len(k.integrate.signatures))
    """,
}


@pytest.mark.parametrize("case", CASES)
def test_the_plant_is_compiled_before_a_device_is_asked(case: str) -> None:
    script = "from bowden.sim import _kernels as k\n" + textwrap.dedent(CASES[case])
    before = subprocess.run([sys.executable, "-c", "from bowden.sim import _kernels as k\n"
                             "print(len(k.integrate.signatures))"],
                            capture_output=True, text=True, timeout=300, check=True)
    assert before.stdout.strip() == "0"  # importing compiles nothing: the case below is what does
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300,
                            check=False)
    assert result.returncode == 0, result.stderr
    assert int(result.stdout.strip()) >= 1
