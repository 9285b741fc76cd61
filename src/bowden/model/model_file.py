"""The versioned ``model.json`` file of a :class:`~bowden.model.compensation.CompensationModel`.

Format (version 1)::

    {
      "format": "bowden.compensation_model",
      "version": 1,
      "raising":  {"intercept_nm": 0.05, "slope_m": 0.044, "fit": {...} | null},
      "lowering": {"intercept_nm": 0.02, "slope_m": 0.028, "fit": {...} | null},
      "blend": {"velocity_01_rad_s": -1.0, "velocity_99_rad_s": 1.0},
      "pulley_radius_m": 0.035,
      "provenance": {"source_files": [...], "source_sha256": [...], "created_utc": "...",
                     "tool": "bowden identify", "tool_version": "0.1.0", "notes": ""} | null
    }

where ``fit`` holds ``n, r_squared_ols, r_squared_robust, robust_scale_nm, intercept_se_nm,
slope_se_m``. Every problem on reading names the file and the dotted field.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import Any

from bowden._atomic_file import write_text_atomically
from bowden.errors import ModelFileError, OutputFileError, ParameterError
from bowden.model.compensation import CompensationLine, CompensationModel, LineFitStats, Provenance

FORMAT = "bowden.compensation_model"
VERSION = 1

_FIT_FIELDS = ("n", "r_squared_ols", "r_squared_robust", "robust_scale_nm", "intercept_se_nm", "slope_se_m")


def model_to_dict(model: CompensationModel) -> dict[str, Any]:
    """The JSON-ready dictionary of ``model`` (format version 1)."""

    def line(line: CompensationLine, fit: LineFitStats | None) -> dict[str, Any]:
        return {
            "intercept_nm": line.intercept_nm,
            "slope_m": line.slope_m,
            "fit": asdict(fit) if fit is not None else None,
        }

    provenance = None
    if model.provenance is not None:
        provenance = asdict(model.provenance)
        provenance["source_files"] = list(model.provenance.source_files)
        provenance["source_sha256"] = list(model.provenance.source_sha256)
    return {
        "format": FORMAT,
        "version": VERSION,
        "raising": line(model.raising, model.raising_fit),
        "lowering": line(model.lowering, model.lowering_fit),
        "blend": {
            "velocity_01_rad_s": model.blend_velocity_01_rad_s,
            "velocity_99_rad_s": model.blend_velocity_99_rad_s,
        },
        "pulley_radius_m": model.pulley_radius_m,
        "provenance": provenance,
    }


def save_model(model: CompensationModel, path: str | Path) -> None:
    """Write ``model`` to ``path`` atomically (a crash never leaves half a file).

    The file gets the usual permissions (``0o666`` less the umask). An existing file is replaced only
    if it is a bowden model file itself, so a wrong path cannot destroy a recording.

    Raises
    ------
    OutputFileError
        ``path`` is a directory, holds something else, or cannot be written (names path and reason).
    """
    path = Path(path)
    text = json.dumps(model_to_dict(model), indent=2, allow_nan=False) + "\n"
    _refuse_replacing_other_files(path)
    try:
        write_text_atomically(path, text, durable=True)
    except OSError as error:
        raise OutputFileError(f"cannot write the model to {path}: {error.strerror or error}") from None


def _refuse_replacing_other_files(path: Path) -> None:
    if path.is_dir():
        raise OutputFileError(f"cannot write the model to {path}: it is a directory; give a file name")
    try:
        with path.open("rb") as handle:
            head = handle.read(4096)
    except (FileNotFoundError, NotADirectoryError):
        return
    except OSError as error:
        raise OutputFileError(f"cannot write the model to {path}: {error.strerror or error}") from None
    if head.strip() and f'"{FORMAT}"'.encode() not in head:
        raise OutputFileError(
            f"refusing to replace {path} by the model: it is not a bowden model file "
            f"(it begins {head[:16]!r}); choose another output path"
        )


class _Reader:
    """Pulls typed fields out of the parsed JSON, naming the dotted field on any problem."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, field: str, problem: str) -> ModelFileError:
        return ModelFileError(f"{self.source}: field '{field}' {problem}")

    def mapping(self, data: Mapping[str, Any], key: str, prefix: str = "") -> Mapping[str, Any]:
        value = self.get(data, key, prefix)
        if not isinstance(value, Mapping):
            raise self.fail(prefix + key, f"must be an object, got {type(value).__name__}")
        return value

    def get(self, data: Mapping[str, Any], key: str, prefix: str = "") -> Any:
        if key not in data:
            raise self.fail(prefix + key, "is missing")
        return data[key]

    def number(self, data: Mapping[str, Any], key: str, prefix: str = "") -> float:
        value = self.get(data, key, prefix)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(prefix + key, f"must be a number, got {value!r}")
        if not math.isfinite(value):
            raise self.fail(prefix + key, f"must be finite, got {value!r}")
        return float(value)

    def strings(self, data: Mapping[str, Any], key: str, prefix: str = "") -> tuple[str, ...]:
        value = self.get(data, key, prefix)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.fail(prefix + key, "must be a list of strings")
        return tuple(value)

    def string(self, data: Mapping[str, Any], key: str, prefix: str = "") -> str:
        value = self.get(data, key, prefix)
        if not isinstance(value, str):
            raise self.fail(prefix + key, f"must be a string, got {value!r}")
        return value


def model_from_dict(data: Any, source: str = "model") -> CompensationModel:
    """Build a model from parsed JSON, validating every field (``source`` names the file in errors)."""
    read = _Reader(source)
    if not isinstance(data, Mapping):
        raise ModelFileError(f"{source}: expected a JSON object at the top level")
    if data.get("format") != FORMAT:
        raise read.fail("format", f"must be {FORMAT!r}, got {data.get('format')!r}: not a bowden model file")
    version = read.get(data, "version")
    if version != VERSION:
        raise read.fail(
            "version",
            f"is {version!r}, but this bowden reads version {VERSION}; upgrade bowden or re-identify",
        )

    def line(key: str) -> tuple[CompensationLine, LineFitStats | None]:
        section = read.mapping(data, key)
        prefix = f"{key}."
        try:
            result = CompensationLine(
                intercept_nm=read.number(section, "intercept_nm", prefix),
                slope_m=read.number(section, "slope_m", prefix),
            )
        except ParameterError as error:
            raise read.fail(prefix + "slope_m", f"is invalid: {error}") from None
        fit_data = read.get(section, "fit", prefix)
        if fit_data is None:
            return result, None
        if not isinstance(fit_data, Mapping):
            raise read.fail(prefix + "fit", "must be an object or null")
        values = {name: read.number(fit_data, name, prefix + "fit.") for name in _FIT_FIELDS}
        if not float(values["n"]).is_integer():
            raise read.fail(prefix + "fit.n", f"must be an integer, got {values['n']!r}")
        return result, LineFitStats(
            n=int(values["n"]),
            r_squared_ols=values["r_squared_ols"],
            r_squared_robust=values["r_squared_robust"],
            robust_scale_nm=values["robust_scale_nm"],
            intercept_se_nm=values["intercept_se_nm"],
            slope_se_m=values["slope_se_m"],
        )

    raising, raising_fit = line("raising")
    lowering, lowering_fit = line("lowering")
    blend = read.mapping(data, "blend")
    provenance = None
    prov_data = read.get(data, "provenance")
    if prov_data is not None:
        if not isinstance(prov_data, Mapping):
            raise read.fail("provenance", "must be an object or null")
        p = "provenance."
        try:
            provenance = Provenance(
                source_files=read.strings(prov_data, "source_files", p),
                source_sha256=read.strings(prov_data, "source_sha256", p),
                created_utc=read.string(prov_data, "created_utc", p),
                tool=read.string(prov_data, "tool", p),
                tool_version=read.string(prov_data, "tool_version", p),
                notes=str(prov_data.get("notes", "")),
            )
        except ParameterError as error:
            raise read.fail("provenance.source_sha256", f"is invalid: {error}") from None
    try:
        return CompensationModel(
            raising=raising,
            lowering=lowering,
            raising_fit=raising_fit,
            lowering_fit=lowering_fit,
            blend_velocity_01_rad_s=read.number(blend, "velocity_01_rad_s", "blend."),
            blend_velocity_99_rad_s=read.number(blend, "velocity_99_rad_s", "blend."),
            pulley_radius_m=read.number(data, "pulley_radius_m"),
            provenance=provenance,
        )
    except ParameterError as error:
        raise ModelFileError(f"{source}: {error}") from None


def load_model(path: str | Path) -> CompensationModel:
    """Read and validate a ``model.json``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ModelFileError(f"{path}: no such model file; create one with `bowden identify`") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ModelFileError(f"{path}: cannot read the model file ({error})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise ModelFileError(
            f"{path}: not valid JSON (line {error.lineno}, column {error.colno}: {error.msg})"
        ) from None
    return model_from_dict(data, source=str(path))
