"""Splice a function's parts into its body: short functions in the source, no call on the hot path.

The controller's step (:mod:`bowden.control.step`) is written as a short body that calls a few
*parts*, each a plain function a reviewer can read and a test can call. Run that way, each call costs
the step a frame; so the controller runs, and the batch kernel is generated from, the step with its
parts spliced in: each call replaced by the part's own statements, so the step the controller runs is
the one long body it would otherwise have to be written as.

A splice is exact only if the part's statements mean in the caller what they meant in the part. So
a part follows a form that makes that so, and anything else stops the splice with the construct named:

- it is called as a statement ``a, b = part(x, y, …)`` (or ``a = part(…)``) whose arguments are the
  caller's variables of the same names as the part's parameters;
- its last statement is ``return a, b`` (or ``return a``), naming exactly the call's targets, and it
  returns nowhere else;
- it assigns a parameter only if it returns it, and a variable of its own (not a parameter, not
  returned) only if the caller does not use that name; a global it reads is not a caller's name.

Parts may call parts; they are spliced in turn.
"""

from __future__ import annotations

import ast
import copy
from collections.abc import Mapping


def module_functions(module: ast.Module) -> dict[str, ast.FunctionDef]:
    """The module's top-level functions by name."""
    return {node.name: node for node in module.body if isinstance(node, ast.FunctionDef)}


def splice(function: ast.FunctionDef, parts: Mapping[str, ast.FunctionDef],
           outer: ast.FunctionDef | None = None) -> ast.FunctionDef:
    """A copy of ``function`` with every call of one of ``parts`` replaced by the part's statements.

    ``outer`` is the function ``function`` is a closure of, whose variables it can read too.
    """
    spliced = copy.deepcopy(function)
    for _ in range(len(parts) + 1):  # each round splices one level of parts called by parts
        found = False
        caller_names = _variables(spliced) | (_variables(outer) if outer else set())
        for node in ast.walk(spliced):
            for field in ("body", "orelse", "finalbody"):
                statements = getattr(node, field, None)
                if isinstance(statements, list) and any(_part_call(s, parts) for s in statements):
                    setattr(node, field, _spliced_statements(statements, parts, caller_names))
                    found = True
        if not found:
            _check_no_call_left(spliced, parts)
            return spliced
    raise ValueError(f"{function.name}: its parts call each other in a circle")


def _check_no_call_left(function: ast.FunctionDef, parts: Mapping[str, ast.FunctionDef]) -> None:
    """A part called any other way (inside an expression) would stay a call: the form forbids it."""
    for node in ast.walk(function):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in parts:
            raise ValueError(f"{ast.unparse(node)!r}: a part is called only as 'a, b = part(...)'")


def _part_call(statement: ast.stmt, parts: Mapping[str, ast.FunctionDef]) -> bool:
    value = getattr(statement, "value", None)
    return isinstance(value, ast.Call) and isinstance(value.func, ast.Name) and value.func.id in parts


def _spliced_statements(statements: list[ast.stmt], parts: Mapping[str, ast.FunctionDef],
                        caller_names: set[str]) -> list[ast.stmt]:
    out: list[ast.stmt] = []
    for statement in statements:
        if _part_call(statement, parts):
            out.extend(_part_body(statement, parts, caller_names))
        else:
            out.append(statement)
    return out


def _part_body(statement: ast.stmt, parts: Mapping[str, ast.FunctionDef],
               caller_names: set[str]) -> list[ast.stmt]:
    """The statements of the part ``statement`` calls, checked against the form above."""
    call = statement.value  # type: ignore[attr-defined]
    part = parts[call.func.id]
    where = f"{ast.unparse(statement)!r}"
    if not isinstance(statement, ast.Assign) or len(statement.targets) != 1:
        raise ValueError(f"{where}: a part is called as one assignment, 'a, b = part(...)'")
    targets = _names_of(statement.targets[0], where)
    parameters = [argument.arg for argument in part.args.args]
    if part.args.vararg or part.args.kwarg or part.args.kwonlyargs or part.args.defaults or call.keywords:
        raise ValueError(f"{where}: a part takes positional parameters only")
    arguments = [getattr(argument, "id", None) for argument in call.args]
    if arguments != parameters:
        raise ValueError(f"{where}: the arguments must be the caller's variables named as "
                         f"{part.name}'s parameters ({', '.join(parameters)})")
    *body, last = part.body
    if _is_docstring(body[0] if body else last):
        body = body[1:]
    if not isinstance(last, ast.Return) or last.value is None:
        raise ValueError(f"{part.name}: its last statement must return what the call assigns")
    if _names_of(last.value, part.name) != targets:
        raise ValueError(f"{where}: {part.name} returns {ast.unparse(last.value)}, not the call's targets")
    _check_body(part, body, set(parameters), set(targets), caller_names - set(targets) - set(parameters))
    return copy.deepcopy(body)


def _check_body(part: ast.FunctionDef, body: list[ast.stmt], parameters: set[str], returned: set[str],
                caller_only: set[str]) -> None:
    for node in (inner for statement in body for inner in ast.walk(statement)):
        if isinstance(node, ast.Return | ast.FunctionDef | ast.Lambda | ast.Global | ast.Nonlocal):
            raise ValueError(f"{part.name}: a part's body has no {type(node).__name__.lower()}")
    names = [node for statement in body for node in ast.walk(statement) if isinstance(node, ast.Name)]
    assigned = {node.id for node in names if not isinstance(node.ctx, ast.Load)}
    globals_read = {node.id for node in names} - assigned - parameters
    if globals_read & caller_only:
        raise ValueError(f"{part.name} reads {sorted(globals_read & caller_only)}, which the caller has "
                         "as its own variables")
    if assigned & parameters - returned:
        raise ValueError(f"{part.name} assigns its parameter(s) {sorted(assigned & parameters - returned)} "
                         "without returning them")
    if (assigned - parameters - returned) & caller_only:
        raise ValueError(f"{part.name}'s own variable(s) {sorted((assigned - returned) & caller_only)} "
                         "are the caller's names too")


def _names_of(node: ast.expr, where: str) -> list[str]:
    elements = node.elts if isinstance(node, ast.Tuple) else [node]
    if not all(isinstance(element, ast.Name) for element in elements):
        raise ValueError(f"{where}: a part's call assigns, and its return names, plain variables")
    return [element.id for element in elements]  # type: ignore[attr-defined]


def _is_docstring(statement: ast.stmt) -> bool:
    return isinstance(statement, ast.Expr) and isinstance(statement.value, ast.Constant) \
        and isinstance(statement.value.value, str)


def _variables(function: ast.FunctionDef) -> set[str]:
    """The names ``function`` (or a function in it) binds: its parameters, what it assigns, its nonlocals."""
    variables = {argument.arg for node in ast.walk(function) if isinstance(node, ast.FunctionDef)
                 for argument in node.args.args}
    for node in ast.walk(function):
        if isinstance(node, ast.Name) and not isinstance(node.ctx, ast.Load):
            variables.add(node.id)
        elif isinstance(node, ast.Nonlocal):
            variables.update(node.names)
    return variables
