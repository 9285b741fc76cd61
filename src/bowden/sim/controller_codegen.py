"""Generate the batch simulator's controller kernel from the controller's own step: one source.

The step closure of :mod:`bowden.control.step` is the only definition of the controller's
arithmetic. A whole simulated trial runs as one compiled loop, which cannot call a Python closure,
so this module rewrites the closure's source into a numba kernel on two vectors:

- each constant the closure folds (a free variable it only reads) becomes ``c[C_NAME]``;
- each variable it keeps across cycles (its ``nonlocal`` names) becomes ``cs[S_NAME]`` (bools as 0/1);
- ``return Command((...))`` writes the five fields to ``out``; ``return fault_command(...)`` writes
  the safe command with :func:`bowden.control.command.fault_bits`.

Nothing else is rewritten: the arithmetic is the closure's, statement for statement. The kernel reads
its constants from a built controller's own closure cells (``bowden.sim._batch_kernel``), so the
vector cannot disagree with the closure either. Anything the rewrite does not know stops the
generator with the construct named.

    python -m bowden.sim.controller_codegen      # rewrite src/bowden/sim/_controller_kernel.py

``tests/sim/test_controller_codegen.py`` fails when the committed kernel differs from what this
generates now, so a change to the step that is not regenerated does not land.
"""

from __future__ import annotations

import ast
import inspect
import sys
from pathlib import Path

from bowden.control import step as step_module
from bowden.control.limits import ControllerLimits
from bowden.control.step import spliced_step, step_closure
from bowden.model import CompensationModel, CuffGeometry, Subject
from bowden.model.anthropometry import arm_model
from bowden.model.assistance import AssistanceParameters

KERNEL_FILE = Path(__file__).with_name("_controller_kernel.py")
_COMMAND_FIELDS = 5


def _step_names() -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    """The step's folded constants, its state and the module globals it uses (from a built step)."""
    step = step_closure(
        CompensationModel.from_friction(k=0.1), "paper",
        arm_model(Subject(height_m=1.7, mass_kg=63.0, sex="female"), 0.5), CuffGeometry(),
        AssistanceParameters(support=0.5), ControllerLimits(),
    ).step
    code = step.__code__  # type: ignore[attr-defined]
    tree = _step_tree()
    state = tuple(name for node in ast.walk(tree) if isinstance(node, ast.Nonlocal) for name in node.names)
    constants = tuple(name for name in code.co_freevars if name not in state)
    # The module globals the spliced step reads (its parts' too, which the built step only calls).
    loaded = {node.id for node in ast.walk(tree) if isinstance(node, ast.Name)}
    globals_used = tuple(sorted(name for name in loaded - set(state) - set(constants)
                                if name.startswith("_") and hasattr(step_module, name)))
    return constants, state, globals_used


def _step_tree() -> ast.FunctionDef:
    """The step with its parts spliced in (:func:`bowden.control.step.spliced_step`)."""
    return spliced_step(ast.parse(inspect.getsource(step_module)))[1]


def constant_index(name: str) -> str:
    return f"C_{name.upper()}"


def state_index(name: str) -> str:
    return f"S_{name.upper()}"


class _ToKernel(ast.NodeTransformer):
    """Rewrites the closure's body into the kernel's (see the module docstring)."""

    def __init__(self, constants: tuple[str, ...], state: tuple[str, ...]) -> None:
        self.constants = set(constants)
        self.state = set(state)

    def visit_Nonlocal(self, node: ast.Nonlocal) -> None:
        return None

    def visit_Name(self, node: ast.Name) -> ast.AST:
        if node.id in self.constants:
            if not isinstance(node.ctx, ast.Load):
                raise ValueError(f"the step assigns its folded constant {node.id!r}; keep it in the state")
            return _subscript("c", constant_index(node.id), node.ctx)
        if node.id in self.state:
            return _subscript("cs", state_index(node.id), node.ctx)
        return node

    def visit_Assign(self, node: ast.Assign) -> ast.AST | list[ast.stmt]:
        value = node.value
        if any(_is_state(target, self.state) for target in node.targets) and isinstance(value, ast.Constant):
            node.value = _as_float(value)
        if isinstance(value, ast.Tuple) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Tuple):
            return self._split(node.targets[0], value)
        return self.generic_visit(node)

    def _split(self, targets: ast.Tuple, values: ast.Tuple) -> list[ast.stmt]:
        """``a, b = x, y`` as two assignments (numba stores into an array one element at a time)."""
        assigned = {t.id for t in targets.elts if isinstance(t, ast.Name)}
        read = {n.id for v in values.elts for n in ast.walk(v) if isinstance(n, ast.Name)}
        if assigned & read or len(targets.elts) != len(values.elts):
            raise ValueError(f"cannot split {ast.unparse(targets)} = {ast.unparse(values)}")
        statements: list[ast.stmt] = []
        for target, value in zip(targets.elts, values.elts, strict=True):
            if _is_state(target, self.state) and isinstance(value, ast.Constant):
                value = _as_float(value)
            statements.append(self.visit(ast.Assign(targets=[target], value=value)))
        return statements

    def visit_Return(self, node: ast.Return) -> list[ast.stmt]:
        call = node.value
        if isinstance(call, ast.Call) and isinstance(call.func, ast.Name):
            if call.func.id == "Command" and isinstance(call.args[0], ast.Tuple):
                fields = [self.visit(element) for element in call.args[0].elts]
                return [*_write_out(fields), ast.Return(value=None)]
            if call.func.id == "fault_command":
                bits = ast.Call(func=ast.Name("_fault_bits", ast.Load()),
                                args=[self.visit(arg) for arg in call.args], keywords=[])
                fields = [ast.Constant(0.0), ast.Name("_NAN", ast.Load()), ast.Name("_NAN", ast.Load()), bits,
                          ast.Constant(0.0)]
                return [*_write_out(fields), ast.Return(value=None)]
        raise ValueError(f"the step returns something the kernel cannot write: {ast.unparse(node)}")


def _is_state(target: ast.expr, state: set[str]) -> bool:
    return isinstance(target, ast.Name) and target.id in state


def _as_float(value: ast.Constant) -> ast.Constant:
    return ast.Constant(float(value.value)) if isinstance(value.value, bool) else value


def _subscript(vector: str, index: str, ctx: ast.expr_context) -> ast.Subscript:
    return ast.Subscript(value=ast.Name(vector, ast.Load()), slice=ast.Name(index, ast.Load()), ctx=ctx)


def _write_out(fields: list[ast.expr]) -> list[ast.stmt]:
    if len(fields) != _COMMAND_FIELDS:
        raise ValueError(f"a Command has {_COMMAND_FIELDS} fields, the step returns {len(fields)}")
    return [ast.Assign(targets=[_subscript_int("out", i)], value=field) for i, field in enumerate(fields)]


def _subscript_int(vector: str, index: int) -> ast.Subscript:
    return ast.Subscript(value=ast.Name(vector, ast.Load()), slice=ast.Constant(index), ctx=ast.Store())


def kernel_source() -> str:
    """The text of ``_controller_kernel.py`` for the step as it is now."""
    constants, state, globals_used = _step_names()
    step = _step_tree()
    body = [statement for statement in (_ToKernel(constants, state).visit(s) for s in step.body)
            if statement is not None]
    flat: list[ast.stmt] = []
    for statement in body:
        flat.extend(statement if isinstance(statement, list) else [statement])
    vector = ast.Name("Vector", ast.Load())
    inputs = [ast.arg(arg.arg, ast.Name("float", ast.Load())) for arg in step.args.args]
    kernel = ast.FunctionDef(
        name="controller_step",
        args=ast.arguments(posonlyargs=[], args=[ast.arg("c", vector), ast.arg("cs", vector), *inputs,
                                                 ast.arg("out", vector)],
                           kwonlyargs=[], kw_defaults=[], defaults=[]),
        body=flat, decorator_list=[ast.Name("jit", ast.Load())], returns=ast.Constant(None),
    )
    code = ast.unparse(ast.fix_missing_locations(ast.Module(body=[kernel], type_ignores=[])))
    imported = ", ".join(name for name in globals_used if name != "_fault_bits")
    lines = [
        '"""The controller step compiled for the batch simulator. GENERATED: do not edit.',
        "",
        "Written by ``python -m bowden.sim.controller_codegen`` from the step closure of",
        ":mod:`bowden.control.step` (the one definition of the controller's arithmetic); the constants",
        "are the closure's folded variables (``c``), the state its ``nonlocal`` ones (``cs``).",
        '"""',
        "",
        "# ruff: noqa",
        "import numpy as np",
        "from numpy.typing import NDArray",
        "",
        "from bowden.control.command import fault_bits",
        f"from bowden.control.step import {imported}",
        "from bowden.sim._kernels import jit",
        "",
        "Vector = NDArray[np.float64]",
        f"CONSTANTS = {constants!r}",
        f"STATE = {state!r}",
        *(f"{constant_index(name)} = {i}" for i, name in enumerate(constants)),
        *(f"{state_index(name)} = {i}" for i, name in enumerate(state)),
        "",
        "_fault_bits = jit(fault_bits)",
        "",
        "",
        code,
        "",
    ]
    return "\n".join(lines)


def main() -> int:
    KERNEL_FILE.write_text(kernel_source(), encoding="utf-8")
    print(f"wrote {KERNEL_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
