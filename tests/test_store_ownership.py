"""Meta-test: one study store, one owner (docs/design.md, "Packages and the rules between them").

Every statement that makes or changes a table of the study store (``CREATE TABLE``, ``ALTER TABLE``,
``DROP TABLE``; ``INSERT``, ``UPDATE``, ``DELETE``, ``REPLACE``) is written in ``bowden/store``: the
tables' layout in :mod:`bowden.store.schema` and :mod:`bowden.store.tables`, each table's rows in the
one module that owns them. Queries of the tables are the store's too (typed reads). Runtime, web and
study call those functions. The SQL is found in the
source's string literals (f-strings included), so a write hidden in another module fails here.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import bowden
from bowden.store.schema import STORE_TABLES

PACKAGE = Path(bowden.__file__).parent

# Who may lay out the tables, and who writes each table's rows.
SCHEMA_OWNERS = frozenset({"bowden.store.schema", "bowden.store.tables"})
ROW_OWNERS = {
    "trials": "bowden.store.trials",
    "events": "bowden.store.trials",
    "sample_chunks": "bowden.store.sample_chunks",
    "samples": "bowden.store.sample_chunks",
    "emg_chunks": "bowden.store.emg_chunks",
    "emg": "bowden.store.emg_chunks",
    "participants": "bowden.store.participants",
    "questionnaires": "bowden.store.questionnaires",
    "sessions": "bowden.store.sessions",
    "plan_steps": "bowden.store.sessions",
    "session_trials": "bowden.store.sessions",
    "session_notes": "bowden.store.sessions",
    "outcomes": "bowden.store.study_store",
    "artifacts": "bowden.store.study_store",
}
_SCHEMA_STATEMENT = re.compile(
    r"\b(?:CREATE TABLE(?: IF NOT EXISTS)?|ALTER TABLE|DROP TABLE(?: IF EXISTS)?)\s+\"?(\w+)"
)
# A query of a store table (reads belong to the store too: typed, so its callers never write SQL).
_READ_STATEMENT = re.compile(r"(?<!DELETE )\b(?:FROM|JOIN)\s+\"?(\w+)")
_ROW_STATEMENT = re.compile(
    r"\b(?:INSERT(?: OR \w+)? INTO|REPLACE INTO|UPDATE(?: OR \w+)?|DELETE FROM)\s+\"?(\w+)"
)


def _strings(tree: ast.AST) -> list[str]:
    """Every string literal of a module; an f-string with its holes as ``{}``."""
    inside_fstrings = {
        id(part) for node in ast.walk(tree) if isinstance(node, ast.JoinedStr) for part in node.values
    }
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.JoinedStr):
            found.append("".join(
                part.value if isinstance(part, ast.Constant) and isinstance(part.value, str) else "{}"
                for part in node.values
            ))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and (
            id(node) not in inside_fstrings
        ):
            found.append(node.value)
    return found


def misplaced_writes(source: str, module: str) -> list[str]:
    """The store-table writes in ``source`` that ``module`` may not make, described."""
    problems = []
    for text in _strings(ast.parse(source)):
        for table in _SCHEMA_STATEMENT.findall(text):
            if table in STORE_TABLES and module not in SCHEMA_OWNERS:
                owners = ", ".join(sorted(SCHEMA_OWNERS))
                problems.append(f"{module} lays out table {table!r} (only {owners})")
        if not module.startswith("bowden.store."):
            problems += [
                f"{module} queries table {table!r} (read it through bowden.store)"
                for table in _READ_STATEMENT.findall(text) if table in STORE_TABLES
            ]
        for table in _ROW_STATEMENT.findall(text):
            owner = ROW_OWNERS.get(table)
            if owner is not None and module != owner:
                problems.append(f"{module} writes rows of {table!r} (its one writer is {owner})")
    return problems


def package_writes(package: Path) -> list[str]:
    problems = []
    for path in sorted(package.rglob("*.py")):
        parts = path.relative_to(package.parent).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        problems += misplaced_writes(path.read_text(encoding="utf-8"), module)
    return problems


def test_every_store_table_has_one_writer() -> None:
    assert set(ROW_OWNERS) == set(STORE_TABLES)


def test_only_the_store_writes_the_store() -> None:
    problems = package_writes(PACKAGE)
    assert not problems, "\n".join(problems)


def test_the_rule_finds_a_write_outside_its_owner() -> None:
    source = '''
def close(connection, trial_id, reason):
    connection.execute("UPDATE trials SET ended_utc = ?, stop_reason = ? WHERE id = ?", (1, reason, trial_id))
    connection.execute(f"INSERT OR REPLACE INTO questionnaires ({COLUMNS}) VALUES (?)", rows)
    connection.execute("DELETE FROM events WHERE trial_id = ?", (trial_id,))
    connection.execute("CREATE TABLE IF NOT EXISTS artifacts (name TEXT)")
    connection.execute("SELECT id FROM trials")
'''
    problems = misplaced_writes(source, "bowden.runtime.recorder")
    assert problems == [
        "bowden.runtime.recorder writes rows of 'trials' (its one writer is bowden.store.trials)",
        "bowden.runtime.recorder writes rows of 'questionnaires' "
        "(its one writer is bowden.store.questionnaires)",
        "bowden.runtime.recorder writes rows of 'events' (its one writer is bowden.store.trials)",
        "bowden.runtime.recorder lays out table 'artifacts' (only bowden.store.schema, bowden.store.tables)",
        "bowden.runtime.recorder queries table 'trials' (read it through bowden.store)",
    ]
    # In the owner of trials and events, only the other tables' statements are wrong.
    assert [problem.split(" (")[0] for problem in misplaced_writes(source, "bowden.store.trials")] == [
        "bowden.store.trials writes rows of 'questionnaires'",
        "bowden.store.trials lays out table 'artifacts'",
    ]
