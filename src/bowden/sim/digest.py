"""The digest of the simulator's sources: what a result computed by it depends on.

A sweep's output records it, and a Dask cluster whose workers run another simulator is refused
(:mod:`bowden.engine.cluster`).
"""

from __future__ import annotations

import hashlib
from pathlib import Path


def simulator_digest() -> str:
    """SHA-256 (16 hex digits) of the simulator's Python sources: results depend on its physics."""
    digest = hashlib.sha256()
    root = Path(__file__).parent
    for path in sorted(root.rglob("*.py")):
        digest.update(path.relative_to(root).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]
