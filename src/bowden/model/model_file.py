"""The versioned ``model.json`` file of a :class:`~bowden.model.compensation.CompensationModel`.

Format (version 2; version 1 is the same without ``dynamic`` and still loads)::

    {
      "format": "bowden.compensation_model",
      "version": 1,
      "raising":  {"intercept_nm": 0.05, "slope_m": 0.044, "fit": {...} | null},
      "lowering": {"intercept_nm": 0.02, "slope_m": 0.028, "fit": {...} | null},
      "blend": {"velocity_01_rad_s": -1.0, "velocity_99_rad_s": 1.0},
      "pulley_radius_m": 0.035,
      "provenance": {"source_files": [...], "source_sha256": [...], "created_utc": "...",
                     "tool": "bowden identify", "tool_version": "0.1.0", "notes": ""} | null,
      "dynamic": {"raising": {"intercept_nm": ..., "slope_m": ...}, "lowering": {...},
                  "viscous_nm_s_rad": 0.04, "inertia_kg_m2": 0.0015, "imu_latency_s": 0.05,
                  "reversal_hysteresis_rad_s": 0.07, "reversal_time_s": 0.01, "max_dynamic_nm": 0.6,
                  "recommended": true, "recommendation": "why, one line" (both optional),
                  "recommended_cells": [{"support": "pretension" | "25" | "50", "speed": "V1",
                                         "dynamic": true}, ...] (optional: the choice per cell),
                  "fit": {"n": ..., "viscous_se_nm_s_rad": ..., "inertia_se_kg_m2": ...,
                          "regime_rms_nm": {...}, "paper_rms_nm": {...}}
                          | null} | null,
      "motor": "AK60-6" | null
    }

where ``fit`` holds ``n, r_squared_ols, r_squared_robust, robust_scale_nm, intercept_se_nm,
slope_se_m``. ``motor`` (optional, any version) names the AK-series model the bench data were
recorded with (``bowden identify --motor``; ``bowden.hardware.motors``): ``bowden run`` refuses the
model on another motor unless told (:func:`recorded_motor`). Every problem on reading names the file
and the dotted field.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from bowden._atomic_file import existing_head, write_text_atomically
from bowden.errors import ModelFileError, OutputFileError, ParameterError
from bowden.model.compensation import CompensationModel, Provenance
from bowden.model.dynamic import DynamicCompensation, DynamicFitStats
from bowden.model.lines import CompensationLine, LineFitStats

FORMAT = "bowden.compensation_model"
VERSION = 2
READABLE_VERSIONS = (1, 2)
MOTOR_KEY = "motor"
_DYNAMIC_NUMBERS = (
    "viscous_nm_s_rad",
    "inertia_kg_m2",
    "imu_latency_s",
    "reversal_hysteresis_rad_s",
    "reversal_time_s",
    "max_dynamic_nm",
)

_FIT_FIELDS = ("n", "r_squared_ols", "r_squared_robust", "robust_scale_nm", "intercept_se_nm", "slope_se_m")

# The torque a line gives at zero tension is the transmission's own friction and drag. The suit's
# AK60-6 peaks at 9 Nm (CubeMars AK60-6 specification; rated 3 Nm): an intercept beyond that is not
# friction the motor
# could overcome but a unit or sign error (e.g. mNm), and it would command the motor's full torque.
MAX_INTERCEPT_NM = 9.0
# R² is a fraction of variance in [0, 1]; rounding may put an exact fit a hair outside.
_R_SQUARED_TOLERANCE = 1e-9


def model_to_dict(model: CompensationModel) -> dict[str, Any]:
    """The JSON-ready dictionary of ``model`` (format version 2)."""

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
        "dynamic": None if model.dynamic is None else _dynamic_to_dict(model.dynamic),
    }


def _dynamic_to_dict(dynamic: DynamicCompensation) -> dict[str, Any]:
    out: dict[str, Any] = {
        "raising": {"intercept_nm": dynamic.raising.intercept_nm, "slope_m": dynamic.raising.slope_m},
        "lowering": {"intercept_nm": dynamic.lowering.intercept_nm, "slope_m": dynamic.lowering.slope_m},
    }
    out.update({name: getattr(dynamic, name) for name in _DYNAMIC_NUMBERS})
    out["recommended"] = dynamic.recommended
    out["recommendation"] = dynamic.recommendation
    if dynamic.recommended_cells:
        out["recommended_cells"] = [{"support": support, "speed": speed, "dynamic": choice}
                                    for support, speed, choice in dynamic.recommended_cells]
    fit = dynamic.fit
    out["fit"] = None if fit is None else {
        "n": fit.n,
        "viscous_se_nm_s_rad": fit.viscous_se_nm_s_rad,
        "inertia_se_kg_m2": fit.inertia_se_kg_m2,
        "regime_rms_nm": dict(fit.regime_rms_nm),
        "paper_rms_nm": dict(fit.paper_rms_nm),
    }
    return out


def model_text(model: CompensationModel, *, motor: str | None = None) -> str:
    """The text of ``model``'s file, as :func:`save_model` writes it (``motor``: see the module)."""
    data = model_to_dict(model)
    if motor is not None:
        data[MOTOR_KEY] = motor
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def recorded_motor(path: str | Path) -> str | None:
    """The motor model ``path`` was identified with, or None when the file does not say (older files).

    Raises
    ------
    ModelFileError
        The file cannot be read, is not JSON, or its ``motor`` is not a string.
    """
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ModelFileError(f"{path}: cannot read the model file ({error})") from None
    motor = data.get(MOTOR_KEY) if isinstance(data, Mapping) else None
    if motor is not None and not (isinstance(motor, str) and motor):
        raise ModelFileError(f"{path}: field {MOTOR_KEY!r} must be a motor model name or null, got {motor!r}")
    return motor


def save_model(model: CompensationModel, path: str | Path, *, motor: str | None = None) -> None:
    """Write ``model`` to ``path`` atomically (a crash never leaves half a file).

    ``motor`` is recorded as the AK-series model the bench data came from (None: not recorded).

    The file gets the usual permissions (``0o666`` less the umask). An existing file is replaced only
    if it is a bowden model file itself, so a wrong path cannot destroy a recording.

    Raises
    ------
    OutputFileError
        ``path`` is a directory, holds something else, or cannot be written (names path and reason).
    """
    path = Path(path)
    text = model_text(model, motor=motor)
    _refuse_replacing_other_files(path)
    try:
        write_text_atomically(path, text, durable=True)
    except OSError as error:
        raise OutputFileError(f"cannot write the model to {path}: {error.strerror or error}") from None


def _refuse_replacing_other_files(path: Path) -> None:
    head = existing_head(path, 4096, "the model")
    if head is not None and head.strip() and f'"{FORMAT}"'.encode() not in head:
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
    version = _version(read, data)
    raising, raising_fit = _line(read, data, "raising")
    lowering, lowering_fit = _line(read, data, "lowering")
    if raising.slope_m < lowering.slope_m:  # equal: a frictionless transmission (from_friction(k=0))
        raise read.fail(
            "raising.slope_m",
            f"({raising.slope_m!r} m) must not be below lowering.slope_m ({lowering.slope_m!r} m): "
            "friction in the sheath opposes the cable, so raising needs more motor torque per newton of "
            "arm tension than lowering; the lines look swapped or wrongly split by direction",
        )
    blend = read.mapping(data, "blend")
    provenance = _provenance(read, data)
    dynamic = None
    if version >= 2:
        dynamic_data = read.get(data, "dynamic")
        if dynamic_data is not None:
            dynamic = _dynamic_from_dict(read, dynamic_data)
    try:
        return CompensationModel(
            dynamic=dynamic,
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


def _version(read: _Reader, data: Mapping[str, Any]) -> int:
    """The file's format version, refused unless this bowden reads it."""
    if data.get("format") != FORMAT:
        raise read.fail("format", f"must be {FORMAT!r}, got {data.get('format')!r}: not a bowden model file")
    version = read.get(data, "version")
    if type(version) is not int:  # JSON true would equal 1, and 1.0 is not how bowden writes it
        known = " or ".join(map(str, READABLE_VERSIONS))
        raise read.fail("version", f"must be the integer {known}, got {version!r}")
    if version not in READABLE_VERSIONS:
        raise read.fail(
            "version",
            f"is {version!r}, but this bowden reads versions "
            f"{', '.join(map(str, READABLE_VERSIONS))}; upgrade bowden or re-identify",
        )
    return version


def _line(read: _Reader, data: Mapping[str, Any], key: str) -> tuple[CompensationLine, LineFitStats | None]:
    """The ``raising`` or ``lowering`` line and its fit statistics (None when the file has none)."""
    section = read.mapping(data, key)
    prefix = f"{key}."
    intercept_nm = read.number(section, "intercept_nm", prefix)
    if abs(intercept_nm) > MAX_INTERCEPT_NM:
        raise read.fail(
            prefix + "intercept_nm",
            f"is {intercept_nm!r} Nm, beyond the motor's peak torque ({MAX_INTERCEPT_NM:g} Nm): the "
            "torque at zero tension is friction the motor overcomes, so this is a unit or sign "
            "error; re-identify the model",
        )
    try:
        slope_m = read.number(section, "slope_m", prefix)
        result = CompensationLine(intercept_nm=intercept_nm, slope_m=slope_m)
    except ParameterError as error:
        raise read.fail(prefix + "slope_m", f"is invalid: {error}") from None
    fit_data = read.get(section, "fit", prefix)
    if fit_data is None:
        return result, None
    if not isinstance(fit_data, Mapping):
        raise read.fail(prefix + "fit", "must be an object or null")
    values = {name: read.number(fit_data, name, prefix + "fit.") for name in _FIT_FIELDS}
    _check_fit(read, values, prefix + "fit.")
    try:
        return result, LineFitStats(
            n=int(values["n"]),
            r_squared_ols=values["r_squared_ols"],
            r_squared_robust=values["r_squared_robust"],
            robust_scale_nm=values["robust_scale_nm"],
            intercept_se_nm=values["intercept_se_nm"],
            slope_se_m=values["slope_se_m"],
        )
    except ParameterError as error:
        raise read.fail(prefix + "fit", f"is invalid: {error}") from None


def _provenance(read: _Reader, data: Mapping[str, Any]) -> Provenance | None:
    """Where the model came from (None when the file does not say)."""
    prov_data = read.get(data, "provenance")
    if prov_data is None:
        return None
    if not isinstance(prov_data, Mapping):
        raise read.fail("provenance", "must be an object or null")
    p = "provenance."
    try:
        return Provenance(
            source_files=read.strings(prov_data, "source_files", p),
            source_sha256=read.strings(prov_data, "source_sha256", p),
            created_utc=read.string(prov_data, "created_utc", p),
            tool=read.string(prov_data, "tool", p),
            tool_version=read.string(prov_data, "tool_version", p),
            notes=str(prov_data.get("notes", "")),
        )
    except ParameterError as error:
        raise read.fail("provenance.source_sha256", f"is invalid: {error}") from None


def _dynamic_from_dict(read: _Reader, data: Any) -> DynamicCompensation:
    if not isinstance(data, Mapping):
        raise read.fail("dynamic", "must be an object or null")
    lines = {}
    for key in ("raising", "lowering"):
        section = read.mapping(data, key, "dynamic.")
        prefix = f"dynamic.{key}."
        try:
            lines[key] = CompensationLine(
                intercept_nm=read.number(section, "intercept_nm", prefix),
                slope_m=read.number(section, "slope_m", prefix),
            )
        except ParameterError as error:
            raise read.fail(prefix + "slope_m", f"is invalid: {error}") from None
        if abs(lines[key].intercept_nm) > MAX_INTERCEPT_NM:
            raise read.fail(
                prefix + "intercept_nm", f"is beyond the motor's peak torque ({MAX_INTERCEPT_NM:g} Nm)"
            )
    numbers: dict[str, Any] = {name: read.number(data, name, "dynamic.") for name in _DYNAMIC_NUMBERS}
    choice: dict[str, Any] = {}
    if "recommended" in data:
        if not isinstance(data["recommended"], bool):
            raise read.fail("dynamic.recommended", f"must be true or false, got {data['recommended']!r}")
        choice["recommended"] = data["recommended"]
    if "recommendation" in data:
        choice["recommendation"] = read.string(data, "recommendation", "dynamic.")
    if "recommended_cells" in data:
        choice["recommended_cells"] = _recommended_cells(read, data["recommended_cells"])
    fit = None
    fit_data = read.get(data, "fit", "dynamic.")
    if fit_data is not None:
        fit = _dynamic_fit_from_dict(read, fit_data)
    try:
        compensation = DynamicCompensation(
            raising=lines["raising"], lowering=lines["lowering"], fit=fit, **numbers
        )
        return replace(compensation, **choice)
    except ParameterError as error:
        raise read.fail("dynamic", f"is invalid: {error}") from None


def _recommended_cells(read: _Reader, data: Any) -> tuple[tuple[str, str, bool], ...]:
    if not isinstance(data, list):
        raise read.fail("dynamic.recommended_cells", "must be a list of {support, speed, dynamic} objects")
    cells = []
    for index, cell in enumerate(data):
        field = f"dynamic.recommended_cells[{index}]"
        if not (isinstance(cell, Mapping) and isinstance(cell.get("support"), str)
                and isinstance(cell.get("speed"), str) and isinstance(cell.get("dynamic"), bool)):
            raise read.fail(field, f"must be {{\"support\": text, \"speed\": text, \"dynamic\": true or "
                                   f"false}}, got {cell!r}")
        cells.append((cell["support"], cell["speed"], cell["dynamic"]))
    return tuple(cells)


def _dynamic_fit_from_dict(read: _Reader, data: Any) -> DynamicFitStats:
    prefix = "dynamic.fit."
    if not isinstance(data, Mapping):
        raise read.fail("dynamic.fit", "must be an object or null")

    def table(key: str) -> tuple[tuple[str, float], ...]:
        section = read.mapping(data, key, prefix)
        return tuple((str(name), read.number(section, name, f"{prefix}{key}.")) for name in section)

    n = read.number(data, "n", prefix)
    if not (n.is_integer() and n >= 0):
        raise read.fail(prefix + "n", f"must be a non-negative integer, got {n!r}")
    try:
        return DynamicFitStats(
            n=int(n),
            viscous_se_nm_s_rad=read.number(data, "viscous_se_nm_s_rad", prefix),
            inertia_se_kg_m2=read.number(data, "inertia_se_kg_m2", prefix),
            regime_rms_nm=table("regime_rms_nm"),
            paper_rms_nm=table("paper_rms_nm"),
        )
    except ParameterError as error:
        raise read.fail("dynamic.fit", f"is invalid: {error}") from None


def _check_fit(read: _Reader, values: Mapping[str, float], prefix: str) -> None:
    """Ranges of the fit statistics: a count, fractions of variance, non-negative spreads."""
    if not (float(values["n"]).is_integer() and values["n"] >= 0):
        raise read.fail(prefix + "n", f"must be a non-negative integer (a sample count), got {values['n']!r}")
    for name in ("r_squared_ols", "r_squared_robust"):
        if not -_R_SQUARED_TOLERANCE <= values[name] <= 1.0 + _R_SQUARED_TOLERANCE:
            raise read.fail(prefix + name, f"must be in [0, 1] (a share of variance), got {values[name]!r}")
    for name in ("robust_scale_nm", "intercept_se_nm", "slope_se_m"):
        if values[name] < 0.0:
            raise read.fail(prefix + name, f"must be >= 0 (a spread), got {values[name]!r}")


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
