"""The lab's own conditions and speeds a study store has recorded, and the check that keeps them one.

A name keeps one meaning in a study: ``support_70`` defined as 0.7 today cannot become 0.6 next
week. What a store holds is read from the session plans (each stores its protocol's catalogue) and
the trials (each records its condition's support and its speed's peak), and a new definition — the
``--define-condition`` and ``--define-speed`` flags of ``bowden serve`` and ``bowden run`` — must
agree with it. The paper's names never need it: their meaning is fixed in ``bowden.contracts``.
"""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

from bowden.contracts import CONDITIONS, SPEEDS
from bowden.errors import ParameterError
from bowden.protocol.catalogue import PAPER, Catalogue
from bowden.store.connection import connect
from bowden.store.sessions import session_protocols
from bowden.store.trials import condition_supports, speed_peaks


def stored_catalogue(connection: sqlite3.Connection) -> Catalogue:
    """The custom conditions and speeds recorded in the store of ``connection`` (plans and trials)."""
    tables = {str(r[0]) for r in connection.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    catalogue = PAPER
    if "sessions" in tables:
        for protocol in session_protocols(connection):
            catalogue = catalogue.merged(Catalogue.from_json(json.loads(protocol).get("catalogue")))
    if "trials" in tables:
        conditions = [
            (name, support) for name, support in condition_supports(connection) if name not in CONDITIONS
        ]
        speeds = [(name, peak) for name, peak in speed_peaks(connection) if name not in SPEEDS]
        for name, support in conditions:
            catalogue = catalogue.merged(Catalogue(conditions=((name, support),)))
        for name, peak in speeds:
            catalogue = catalogue.merged(Catalogue(speeds=((name, peak),)))
    return catalogue


def checked_catalogue(path: Path, catalogue: Catalogue) -> Catalogue:
    """``catalogue`` with the store's own definitions added; a name given another meaning is refused.

    A store that does not exist yet has none. Raises :class:`~bowden.errors.ParameterError` (one
    line naming the store) when a definition contradicts what the store recorded.
    """
    if not Path(path).is_file():
        return catalogue
    with connect(Path(path)) as connection:
        stored = stored_catalogue(connection)
    try:
        return catalogue.merged(stored)
    except ParameterError as error:
        raise ParameterError(f"{path}: {error}") from None
