"""Splicing a function's parts into it (bowden.control.splice): exact, or refused with the construct named."""

from __future__ import annotations

import ast
import textwrap

import pytest

from bowden.control.splice import module_functions, splice

PARTS = '''
def _scaled(x, gain):
    """Docstrings are left out."""
    y = x * gain
    if y > 1.0:
        y = 1.0
    return y


def _both(x, gain):
    y = _scaled(x, gain)
    x += gain
    return x, y
'''
EARLY_RETURN = "def _p(x, gain):\n    if x:\n        return x\n    y = x\n    return y\n"
ASSIGNS_PARAMETER = "def _p(x, gain):\n    x = 2 * gain\n    y = x\n    return y\n"
OWN_VARIABLE = "def _p(x, gain):\n    t = x * gain\n    y = t\n    return y\n"
READS_GLOBAL = "_k = 1\ndef _p(x, gain):\n    y = x * _k\n    return y\n"
CIRCLE = "def _p(x):\n    x = _q(x)\n    return x\ndef _q(x):\n    x = _p(x)\n    return x\n"
CALLS_NESTED = "def f(x, gain):\n    if x:\n        x, y = _both(x, gain)\n    return x * y\n"


def _spliced(caller: str, parts: str = PARTS) -> str:
    module = ast.parse(textwrap.dedent(caller) + textwrap.dedent(parts))
    functions = module_functions(module)
    part_names = {name: node for name, node in functions.items() if name.startswith("_")}
    return ast.unparse(splice(functions["f"], part_names))


def test_a_call_becomes_the_part_s_statements_without_its_return() -> None:
    assert _spliced("def f(x, gain):\n    y = _scaled(x, gain)\n    return y + 1\n") == textwrap.dedent("""\
        def f(x, gain):
            y = x * gain
            if y > 1.0:
                y = 1.0
            return y + 1""")


def test_parts_called_by_parts_are_spliced_in_turn_and_compute_what_the_calls_do() -> None:
    spliced = _spliced(CALLS_NESTED)
    assert "_both" not in spliced and "_scaled" not in spliced
    results = []
    for source in (spliced, CALLS_NESTED):
        namespace: dict[str, object] = {}
        exec(compile(source + "\n" + textwrap.dedent(PARTS), "<test>", "exec"), namespace)
        results.append([namespace["f"](x, gain) for x, gain in [(0.2, 0.5), (3.0, 2.0), (0.9, 0.1)]])  # type: ignore[operator]
    assert results[0] == results[1] == [0.7 * 0.1, 5.0 * 1.0, 1.0 * 0.09000000000000001]


@pytest.mark.parametrize(
    ("caller", "parts", "words"),
    [
        ("def f(a, gain):\n    y = _scaled(a, gain)\n", PARTS, "the caller's variables named as _scaled's"),
        ("def f(x, gain):\n    w = _scaled(x, gain)\n", PARTS, r"returns y, not the call's targets"),
        ("def f(x, gain):\n    y = _scaled(x, gain) + 1\n", PARTS, r"called only as 'a, b = part\(...\)'"),
        ("def f(x, gain):\n    y = _p(x, gain)\n", EARLY_RETURN, "a part's body has no return"),
        ("def f(x, gain):\n    y = _p(x, gain)\n", ASSIGNS_PARAMETER,
         r"assigns its parameter\(s\) \['x'\] without returning them"),
        ("def f(x, gain):\n    t = 3\n    y = _p(x, gain)\n    return t + y\n", OWN_VARIABLE,
         r"own variable\(s\) \['t'\] are the caller's"),
        ("def f(x, gain):\n    _k = 2\n    y = _p(x, gain)\n    return _k + y\n", READS_GLOBAL,
         r"reads \['_k'\], which the caller has"),
        ("def f(x):\n    x = _p(x)\n", CIRCLE, "call each other in a circle"),
    ],
)
def test_what_would_not_mean_the_same_spliced_is_refused_with_the_construct_named(
    caller: str, parts: str, words: str,
) -> None:
    with pytest.raises(ValueError, match=words):
        _spliced(caller, parts)
