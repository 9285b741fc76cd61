"""Output paths of the commands, checked before any work is done.

A command refuses an output that would overwrite one of its inputs (``bowden analyze study.db
--report study.db`` used to replace the whole store by the report) and an output that cannot be
written (a directory, a missing or read-only folder), so a bad path costs neither the input nor a
long computation, and never leaves half a result behind.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

from bowden.errors import OutputFileError


def same_file(first: Path, second: Path) -> bool:
    """Whether two paths name one file (through symbolic links, ``..`` and hard links)."""
    try:
        return os.path.samefile(first, second)
    except OSError:  # one of them does not exist (yet): compare where they would point
        return first.resolve() == second.resolve()


def refuse_overwriting_inputs(flag: str, output: Path, inputs: Mapping[Path, str]) -> None:
    """Raise ``OutputFileError`` if ``output`` is one of ``inputs`` (path → what it is, for the message)."""
    for path, what in inputs.items():
        if same_file(output, path):
            raise OutputFileError(
                f"{flag} {output} is {what}: writing there would destroy it; choose another path"
            )


def check_output_file(what: str, path: Path, *, create_parents: bool) -> None:
    """Raise ``OutputFileError`` unless a file can be written at ``path``.

    ``what`` names the output in the message (``"the report (--report)"``). ``create_parents`` says
    whether the writer makes missing folders (then the nearest existing one must take new entries) or
    needs the folder to exist already.
    """
    if path.is_dir():
        raise OutputFileError(f"cannot write {what} to {path}: it is a directory; give a file name")
    if not create_parents and not path.parent.is_dir():
        reason = "is not a directory" if path.parent.exists() else "does not exist"
        raise OutputFileError(f"cannot write {what} to {path}: the folder {path.parent} {reason}")
    _probe_folder(what, path, path.parent)


def check_output_directory(what: str, path: Path) -> None:
    """Raise ``OutputFileError`` unless ``path`` is (or can be made) a directory that takes files."""
    if path.exists() and not path.is_dir():
        raise OutputFileError(f"cannot write {what} to {path}: it exists and is not a directory")
    _probe_folder(what, path, path)


def _probe_folder(what: str, path: Path, folder: Path) -> None:
    """Create and delete a file in ``folder`` (or its nearest existing ancestor).

    Permission bits do not tell: root passes ``os.access`` on a read-only file system, and pseudo file
    systems such as ``/proc`` refuse new files whatever their modes say. Creating one does tell.
    """
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise OutputFileError(f"cannot write {what} to {path}: {existing} is not a directory")
    try:
        fd, probe = tempfile.mkstemp(prefix=".bowden-write-check-", dir=existing)
    except OSError as error:
        reason = error.strerror or str(error)
        raise OutputFileError(
            f"cannot write {what} to {path}: {existing} takes no new files ({reason})"
        ) from None
    os.close(fd)
    os.unlink(probe)
