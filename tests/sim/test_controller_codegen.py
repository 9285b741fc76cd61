"""The batch simulator's controller kernel is generated from the controller's step: one source."""

from __future__ import annotations

import ast

import pytest

from bowden.sim import _controller_kernel as ck
from bowden.sim.controller_codegen import KERNEL_FILE, _ToKernel, kernel_source


def test_the_committed_kernel_is_what_the_step_generates_now():
    # A change to bowden/control/step.py must be followed by `python -m bowden.sim.controller_codegen`.
    assert KERNEL_FILE.read_text(encoding="utf-8") == kernel_source(), (
        "src/bowden/sim/_controller_kernel.py is out of date: run python -m bowden.sim.controller_codegen"
    )


def test_constants_and_state_become_vector_elements_and_bools_floats():
    source = "def step(x):\n nonlocal s, on\n s, on = x * gain, True\n return Command((s, 0, 0, 0, 0))"
    function = ast.parse(source).body[0]
    assert isinstance(function, ast.FunctionDef)
    rewritten = [_ToKernel(("gain",), ("s", "on")).visit(statement) for statement in function.body]
    flat = [s for item in rewritten if item is not None for s in (item if isinstance(item, list) else [item])]
    module = ast.fix_missing_locations(ast.Module(body=flat, type_ignores=[]))
    assert [ast.unparse(s) for s in module.body] == [
        "cs[S_S] = x * c[C_GAIN]", "cs[S_ON] = 1.0",
        "out[0] = cs[S_S]", "out[1] = 0", "out[2] = 0", "out[3] = 0", "out[4] = 0", "return",
    ]


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ("gain = 2.0", "assigns its folded constant 'gain'"),
        ("a, b = b, a", r"cannot split \(a, b\) = \(b, a\)"),
        ("return 3.0", "returns something the kernel cannot write"),
    ],
)
def test_what_the_rewrite_does_not_know_stops_it_with_the_construct_named(body, words):
    statement = ast.parse(body).body[0]
    with pytest.raises(ValueError, match=words):
        _ToKernel(("gain",), ()).visit(statement)


def test_the_kernel_keeps_the_step_s_state_names_in_order():
    assert ck.STATE[:2] == ("last_torque", "last_time") and "started" in ck.STATE
    assert len(set(ck.CONSTANTS)) == len(ck.CONSTANTS) and "dynamic" in ck.CONSTANTS
