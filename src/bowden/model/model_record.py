"""What a trial's metadata records of the compensation model it ran with, so that every trial can be
traced to its model even after ``model.json`` was replaced or moved.

``model_sha256``
    The SHA-256 (hex) of the model file the trial loaded, as ``sha256sum model.json`` prints it; for a
    model that came from no file (``bowden run``'s built-in simulated suit, ``bowden study``'s model
    in memory) the SHA-256 of the file :func:`~bowden.model.model_file.save_model` writes for it.
``model_coefficients``
    The numbers the controller used: both lines (intercept, slope), the blend, the pulley radius and
    the dynamic compensation's parameters (None without one); the fit statistics and provenance stay
    in the file.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any, Final

from bowden.errors import ModelFileError
from bowden.model.compensation import CompensationModel
from bowden.model.model_file import model_text, model_to_dict

MODEL_SHA256_KEY: Final = "model_sha256"
MODEL_COEFFICIENTS_KEY: Final = "model_coefficients"


def model_sha256(model: CompensationModel) -> str:
    """The SHA-256 of the file :func:`~bowden.model.model_file.save_model` writes for ``model``."""
    return hashlib.sha256(model_text(model).encode()).hexdigest()


def file_sha256(path: str | Path) -> str:
    """The SHA-256 of a model file's bytes.

    Raises
    ------
    ModelFileError
        The file cannot be read (names it).
    """
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as error:
        raise ModelFileError(f"cannot read the model file {path}: {error.strerror or error}") from None


def controller_sha256(model: CompensationModel) -> str:
    """The SHA-256 of the coefficients the controller runs (:func:`model_coefficients`) without the
    per-cell recommendation, which ``bench validate -o MODEL`` rewrites and no block depends on."""
    coefficients = model_coefficients(model)
    if coefficients["dynamic"] is not None:
        coefficients["dynamic"] = {key: value for key, value in coefficients["dynamic"].items()
                                   if not key.startswith("recommend")}
    return hashlib.sha256(json.dumps(coefficients, sort_keys=True).encode()).hexdigest()


def model_coefficients(model: CompensationModel) -> dict[str, Any]:
    """The coefficients of ``model`` the controller uses, JSON-ready (the file's without fits)."""
    data = model_to_dict(model)
    coefficients: dict[str, Any] = {
        line: {"intercept_nm": data[line]["intercept_nm"], "slope_m": data[line]["slope_m"]}
        for line in ("raising", "lowering")
    }
    coefficients["blend"] = data["blend"]
    coefficients["pulley_radius_m"] = data["pulley_radius_m"]
    dynamic = data.get("dynamic")
    coefficients["dynamic"] = (
        None if dynamic is None else {key: value for key, value in dynamic.items() if key != "fit"}
    )
    return coefficients


def model_record(model: CompensationModel, path: str | Path | None = None) -> dict[str, Any]:
    """The trial metadata of ``model``: its SHA-256 (of ``path``, the file it was loaded from, if
    any) and its coefficients.

    Raises
    ------
    ModelFileError
        ``path`` cannot be read.
    """
    digest = file_sha256(path) if path is not None else model_sha256(model)
    return {MODEL_SHA256_KEY: digest, MODEL_COEFFICIENTS_KEY: model_coefficients(model)}
