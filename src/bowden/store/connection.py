"""One short-lived connection to the study-store file, with the runtime's settings (WAL, checks).

The server's registry, session plans and questionnaires each open the file for one operation and
close it again, so they never hold a lock while the recorder commits a trial into the same file.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from bowden.errors import StoreError
from bowden.store.schema import configure_connection


@contextmanager
def connect(path: Path) -> Iterator[sqlite3.Connection]:
    """A configured connection to ``path``, closed at the end of the ``with`` block.

    Raises
    ------
    StoreError
        If the file cannot be opened, is not a bowden store, or a statement fails (names the file).
    """
    try:
        connection = sqlite3.connect(path, timeout=5.0)
    except sqlite3.Error as error:
        raise StoreError(f"cannot open the study store {path}: {error}") from None
    try:
        configure_connection(connection)
        yield connection
    except sqlite3.Error as error:
        raise StoreError(f"the study store {path}: {error}") from None
    finally:
        connection.close()
