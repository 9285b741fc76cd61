"""The sweep's output directory: one Parquet part per finished task, written atomically, and the tables.

Layout::

    OUT/spec.json                        the spec, and a digest of the simulator's source
    OUT/models/<suit_id>.json            identified compensation model of each suit (model.json format)
    OUT/parts/<point_id>/<participant>.parquet   rows of one task, as soon as it finishes
    OUT/results.parquet                  all rows of the spec's points (written at the end)
    OUT/points.parquet                   one row per configuration: means, ranks, Pareto front

Every file is written to a temporary name in the same directory and renamed into place, so a reader
(or a re-run) never sees half a file, and a task's rows are on disk the moment it finishes: a run
killed at any time keeps everything it finished. A re-run with the same spec skips the parts it
finds. Results computed with another spec or another simulator are never mixed in: the directory is
refused (``--force`` clears it).
"""

from __future__ import annotations

import json
import logging
import os
import shutil
from collections.abc import Iterable
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from bowden.errors import OutputFileError, ParameterError
from bowden.model import CompensationModel
from bowden.model.model_file import load_model, save_model
from bowden.sim.digest import simulator_digest
from bowden.sweep.spec import SweepSpec
from bowden.sweep.task import RESULT_COLUMNS

_log = logging.getLogger(__name__)

SPEC_FILE = "spec.json"
RESULTS_FILE = "results.parquet"
POINTS_FILE = "points.parquet"


class SweepDirectory:
    """Reads and writes one sweep's output directory (layout in the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    # --- the spec -------------------------------------------------------------------------------

    def prepare(self, spec: SweepSpec, *, force: bool = False) -> None:
        """Create the directory for ``spec``; refuse one holding another spec's or simulator's results."""
        if self.path.exists() and not self.path.is_dir():
            raise OutputFileError(f"the sweep directory {self.path} is a file; use another --out directory")
        record = {"spec": spec.to_dict(), "simulator_sha256": simulator_digest()}
        spec_file = self.path / SPEC_FILE
        if force:
            for name in ("parts", "models"):
                shutil.rmtree(self.path / name, ignore_errors=True)
            for name in (SPEC_FILE, RESULTS_FILE, POINTS_FILE):
                (self.path / name).unlink(missing_ok=True)
        elif spec_file.exists():
            try:
                existing = json.loads(spec_file.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise ParameterError(
                    f"{spec_file} is unreadable ({exc}); use --force to start again"
                ) from None
            if existing.get("spec") != record["spec"]:
                raise ParameterError(
                    f"{self.path} holds a sweep with another spec ({spec_file}); use another --out "
                    "directory or --force to start again"
                )
            if existing.get("simulator_sha256") != record["simulator_sha256"]:
                raise ParameterError(
                    f"{self.path} holds results of another version of the simulator (bowden.sim changed "
                    "since); use another --out directory or --force to recompute them"
                )
        elif self.path.exists() and any(self.path.iterdir()):
            raise ParameterError(
                f"{self.path} is not empty and holds no sweep ({SPEC_FILE} missing); "
                "use another --out directory"
            )
        try:
            (self.path / "parts").mkdir(parents=True, exist_ok=True)
            (self.path / "models").mkdir(exist_ok=True)
        except OSError as exc:
            raise OutputFileError(f"cannot create the sweep directory {self.path}: {exc.strerror}") from None
        self._write_text(spec_file, json.dumps(record, indent=2) + "\n")

    # --- task parts -----------------------------------------------------------------------------

    def part_path(self, point_id: str, participant: str) -> Path:
        return self.path / "parts" / point_id / f"{participant}.parquet"

    def has_part(self, point_id: str, participant: str) -> bool:
        """Whether this task's rows are stored and readable; a damaged part is removed, to be redone."""
        path = self.part_path(point_id, participant)
        if not path.exists():
            return False
        try:
            pq.read_metadata(path)  # the footer only: cheap, and fails on a truncated or foreign file
        except (OSError, pa.ArrowException):
            _log.warning("sweep part %s is damaged; computing it again", path)
            path.unlink(missing_ok=True)
            return False
        return True

    def write_part(self, point_id: str, participant: str, frame: pd.DataFrame) -> None:
        """Store one finished task's rows (atomic)."""
        path = self.part_path(point_id, participant)
        path.parent.mkdir(parents=True, exist_ok=True)
        self._write_parquet(path, frame)

    def read_parts(self, keys: Iterable[tuple[str, str]]) -> pd.DataFrame:
        """All rows of the given ``(point_id, participant)`` parts, in that order."""
        frames = []
        for point, participant in keys:
            path = self.part_path(point, participant)
            try:
                frames.append(pd.read_parquet(path))
            except (OSError, pa.ArrowException) as exc:
                raise OutputFileError(
                    f"cannot read the sweep part {path} ({exc}); delete it and run the sweep again to redo it"
                ) from None
        if not frames:
            return pd.DataFrame(columns=list(RESULT_COLUMNS))
        return pd.concat(frames, ignore_index=True).loc[:, list(RESULT_COLUMNS)]

    # --- identified models ----------------------------------------------------------------------

    def model_path(self, suit_id: str) -> Path:
        return self.path / "models" / f"{suit_id}.json"

    def load_model(self, suit_id: str) -> CompensationModel | None:
        path = self.model_path(suit_id)
        return load_model(path) if path.exists() else None

    def save_model(self, suit_id: str, model: CompensationModel) -> None:
        path = self.model_path(suit_id)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        save_model(model, tmp)
        os.replace(tmp, path)

    # --- tables ---------------------------------------------------------------------------------

    def write_results(self, frame: pd.DataFrame) -> Path:
        path = self.path / RESULTS_FILE
        self._write_parquet(path, frame)
        return path

    def write_points(self, frame: pd.DataFrame) -> Path:
        path = self.path / POINTS_FILE
        self._write_parquet(path, frame)
        return path

    # --- atomic writes --------------------------------------------------------------------------

    def _write_parquet(self, path: Path, frame: pd.DataFrame) -> None:
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            frame.to_parquet(tmp, index=False)
            os.replace(tmp, path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise OutputFileError(f"cannot write {path}: {exc.strerror or exc}") from None

    def _write_text(self, path: Path, text: str) -> None:
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, path)
        except OSError as exc:
            tmp.unlink(missing_ok=True)
            raise OutputFileError(f"cannot write {path}: {exc.strerror or exc}") from None
