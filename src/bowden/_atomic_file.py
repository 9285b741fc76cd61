"""Whole-file writes that a crash cannot leave half done, with the permissions a plain ``open`` gives.

The text goes to a temporary file in the destination's folder, which is then renamed over the
destination: readers see the old file or the new one, never a mixture. ``tempfile.mkstemp`` would make
the temporary file (hence the result) readable by its owner only; here it is created with mode
``0o666`` and the process umask applies, as for any file a program writes (``0o644`` under the usual
umask ``022``).
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

from bowden.errors import OutputFileError

_ATTEMPTS = 100


def write_text_atomically(path: str | Path, text: str, *, durable: bool = False) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path.

    ``durable`` also fsyncs the data before the rename, so the new content survives a power cut.
    Raises ``OSError`` (the folder is missing or read-only, the path is a directory...).
    """
    path = Path(path)
    folder = path.parent
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_CLOEXEC", 0)
    for _ in range(_ATTEMPTS):
        tmp = folder / f".{path.name}.{secrets.token_hex(4)}.tmp"
        try:
            fd = os.open(tmp, flags, 0o666)  # the umask takes its bits off, as for open(path, "w")
            break
        except FileExistsError:
            continue
    else:  # pragma: no cover - 100 collisions of 32 random bits
        raise FileExistsError(f"no free temporary name beside {path}")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(text)
            if durable:
                handle.flush()
                os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return path


def existing_head(path: Path, size: int, what: str) -> bytes | None:
    """The first ``size`` bytes of the file ``what`` is about to replace, None when there is none.

    Callers refuse to replace a file whose head is not one of theirs, so that an output path can
    never overwrite a recording. Raises ``OutputFileError`` (naming ``what``) for a directory or an
    unreadable file.
    """
    if path.is_dir():
        raise OutputFileError(f"cannot write {what} to {path}: it is a directory; give a file name")
    try:
        with path.open("rb") as handle:
            return handle.read(size)
    except (FileNotFoundError, NotADirectoryError):
        return None
    except OSError as error:
        raise OutputFileError(f"cannot write {what} to {path}: {error.strerror or error}") from None
