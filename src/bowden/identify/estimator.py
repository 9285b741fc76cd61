"""The identification pipeline as a scikit-learn style estimator.

``TransmissionIdentifier().fit(recording)`` reads (if given paths), filters, selects steady-state
samples, fits one MATLAB-equal robust line per direction of cable travel (motor torque against
load-cell tension, paper section "Model identification") and builds the controller's
:class:`bowden.model.CompensationModel` with fit statistics and provenance. Learned attributes end in
an underscore: ``model_``, ``raising_fit_``, ``lowering_fit_``, ``selection_``, ``summary_``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Self

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from bowden import __version__
from bowden.errors import FitError, ParameterError, RecordingError
from bowden.identify.dynamic import DEFAULT_IMU_LATENCY_S, DynamicIdentification, identify_dynamic
from bowden.identify.preprocess import (
    DIRECTIONS,
    LOWERING,
    RAISING,
    PreprocessSettings,
    SteadyStateSelection,
    bench_preprocess,
)
from bowden.identify.recording import (
    BenchRecording,
    RecordingLimits,
    bench_recording_from_frame,
    read_bench_recording,
)
from bowden.identify.robustfit import BISQUARE_TUNE, RobustFit, robustfit
from bowden.identify.summary import IdentificationSummary, SummaryThresholds, identification_summary
from bowden.model import CompensationLine, CompensationModel, LineFitStats, Provenance
from bowden.model.model_file import MAX_INTERCEPT_NM

RecordingInput = BenchRecording | pd.DataFrame | str | Path | Sequence[str | Path]

_PARAMETERS = (
    "preprocessing",
    "pulley_radius_m",
    "blend_velocity_01_rad_s",
    "blend_velocity_99_rad_s",
    "min_samples_per_direction",
    "tune",
    "limits",
    "thresholds",
    "dynamic",
    "imu_latency_s",
)


# sqrt(m_raise·m_lower)/R beyond this factor (either way) cannot be friction or torque-constant error.
MAX_SLOPE_SCALE = 2.0
# Unit mix-ups that scale the slopes by a known factor, and what to say about them.
_UNIT_FACTORS = (
    (9.80665, "tension_n looks like kilogram-force or daN (multiply by 9.80665 or 10 for newtons)"),
    (4.44822, "tension_n looks like pound-force (multiply by 4.44822 for newtons)"),
    (1e3, "motor_torque_nm looks like mNm, or tension_n like kN"),
    (1e-3, "tension_n looks like mN, or motor_torque_nm like kNm"),
    (1 / 9.80665, "motor_torque_nm looks like kgf·m (multiply by 9.80665 for Nm)"),
)


def _check_loadable(raising: RobustFit, lowering: RobustFit) -> None:
    """Refuse lines that ``model.json`` could not hold (:func:`bowden.model.model_file.load_model`)."""
    if raising.slope < lowering.slope:
        raise FitError(
            f"the raising line's slope ({1e3 * raising.slope:.4g} mm) is below the lowering line's "
            f"({1e3 * lowering.slope:.4g} mm), which friction cannot do: the directions are swapped; "
            "check the sign of motor_velocity_rad_s (> 0 while the cable is reeled in)"
        )
    for name, fit in ((RAISING, raising), (LOWERING, lowering)):
        if abs(fit.intercept) > MAX_INTERCEPT_NM:
            raise FitError(
                f"the {name} line's intercept is {fit.intercept:.4g} Nm, beyond the motor's peak torque "
                f"({MAX_INTERCEPT_NM:g} Nm): no friction does that; check the units of motor_torque_nm"
            )

class TransmissionIdentifier:
    """Identify the raising and lowering compensation lines from a bench recording.

    Parameters
    ----------
    preprocessing
        Filter and steady-state selection settings (default: the paper's).
    pulley_radius_m
        Spool radius, m (paper: 35 mm); stored in the model and used for the single-bend check.
    blend_velocity_01_rad_s, blend_velocity_99_rad_s
        Elevation velocities of 1 % and 99 % raising-line weight in the model (paper: −1, +1 rad/s).
    min_samples_per_direction
        Fewer steady-state samples than this in a direction is an error (the summary warns earlier,
        see ``thresholds``).
    tune
        Bisquare tuning constant of :func:`robustfit` (MATLAB default 4.685).
    limits
        Unit plausibility limits used when reading files or tables.
    thresholds
        When the summary warns.
    dynamic
        Also identify the dynamic compensation (:mod:`bowden.identify.dynamic`) and store it in the
        model (version 2), which then recommends it. When the recording cannot support it (one spool
        speed), the model keeps the paper's lines only and ``dynamic_error_`` says why.
    imu_latency_s
        Age of the suit's IMU samples on arrival, stored in the dynamic model for its estimator
        (not visible in the bench recording; default
        :data:`bowden.identify.dynamic.DEFAULT_IMU_LATENCY_S`).
    """

    def __init__(
        self,
        *,
        preprocessing: PreprocessSettings | None = None,
        pulley_radius_m: float = 0.035,
        blend_velocity_01_rad_s: float = -1.0,
        blend_velocity_99_rad_s: float = 1.0,
        min_samples_per_direction: int = 50,
        tune: float = BISQUARE_TUNE,
        limits: RecordingLimits | None = None,
        thresholds: SummaryThresholds | None = None,
        dynamic: bool = True,
        imu_latency_s: float = DEFAULT_IMU_LATENCY_S,
    ) -> None:
        self.preprocessing = preprocessing or PreprocessSettings()
        self.pulley_radius_m = pulley_radius_m
        self.blend_velocity_01_rad_s = blend_velocity_01_rad_s
        self.blend_velocity_99_rad_s = blend_velocity_99_rad_s
        self.min_samples_per_direction = min_samples_per_direction
        self.tune = tune
        self.limits = limits or RecordingLimits()
        self.thresholds = thresholds or SummaryThresholds()
        self.dynamic = dynamic
        self.imu_latency_s = imu_latency_s
        self._validate()

    def _validate(self) -> None:
        if not isinstance(self.preprocessing, PreprocessSettings):
            raise ParameterError(f"preprocessing must be PreprocessSettings, got {self.preprocessing!r}")
        if not isinstance(self.limits, RecordingLimits):
            raise ParameterError(f"limits must be RecordingLimits, got {self.limits!r}")
        if not isinstance(self.thresholds, SummaryThresholds):
            raise ParameterError(f"thresholds must be SummaryThresholds, got {self.thresholds!r}")
        if not (
            isinstance(self.pulley_radius_m, int | float)
            and math.isfinite(self.pulley_radius_m)
            and 0.0 < self.pulley_radius_m < 0.5
        ):
            raise ParameterError(f"pulley_radius_m must be in (0, 0.5) m, got {self.pulley_radius_m!r}")
        for name in ("blend_velocity_01_rad_s", "blend_velocity_99_rad_s", "tune"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise ParameterError(f"{name} must be a finite number, got {value!r}")
        if not self.blend_velocity_99_rad_s > self.blend_velocity_01_rad_s:
            raise ParameterError("blend_velocity_99_rad_s must exceed blend_velocity_01_rad_s")
        if self.tune <= 0.0:
            raise ParameterError(f"tune must be positive, got {self.tune!r}")
        if not isinstance(self.dynamic, bool):
            raise ParameterError(f"dynamic must be True or False, got {self.dynamic!r}")
        latency = self.imu_latency_s
        if isinstance(latency, bool) or not isinstance(latency, int | float) or not 0.0 <= latency <= 0.2:
            raise ParameterError(f"imu_latency_s must be in [0, 0.2] s, got {latency!r}")
        count = self.min_samples_per_direction
        if isinstance(count, bool) or not isinstance(count, int) or count < 3:
            raise ParameterError(f"min_samples_per_direction must be an integer >= 3, got {count!r}")

    # --- scikit-learn conventions -------------------------------------------------------------
    def get_params(self, deep: bool = True) -> dict[str, Any]:
        """The constructor parameters (``deep`` is accepted for scikit-learn compatibility)."""
        return {name: getattr(self, name) for name in _PARAMETERS}

    def set_params(self, **params: Any) -> Self:
        """Set constructor parameters (validated) and return self."""
        unknown = sorted(set(params) - set(_PARAMETERS))
        if unknown:
            raise ParameterError(
                f"unknown parameter(s) {', '.join(unknown)}; valid: {', '.join(_PARAMETERS)}"
            )
        for name, value in params.items():
            setattr(self, name, value)
        self._validate()
        return self

    def __repr__(self) -> str:
        defaults = TransmissionIdentifier().get_params()
        changed = {name: value for name, value in self.get_params().items() if value != defaults[name]}
        inner = ", ".join(f"{name}={value!r}" for name, value in changed.items())
        return f"TransmissionIdentifier({inner})"

    # --- fitting -------------------------------------------------------------------------------
    def _as_recording(self, recording: RecordingInput) -> BenchRecording:
        if isinstance(recording, BenchRecording):
            return recording
        if isinstance(recording, pd.DataFrame):
            return bench_recording_from_frame(recording, limits=self.limits)
        return read_bench_recording(recording, limits=self.limits)

    def _fit_direction(self, selection: SteadyStateSelection, direction: str) -> RobustFit:
        count = selection.count(direction)
        if count < self.min_samples_per_direction:
            raise RecordingError(
                f"too few steady-state samples while {direction}: {count} "
                f"(need at least {self.min_samples_per_direction}); "
                f"{selection.rejection_report(direction)}. Record longer constant-speed sweeps in "
                "both directions or relax the PreprocessSettings thresholds"
            )
        fit = robustfit(selection.tension_n(direction), selection.motor_torque_nm(direction), tune=self.tune)
        if not 0.0 < fit.slope < 1.0:
            raise FitError(
                f"the {direction} line has slope {fit.slope:.5g} m, but motor torque per newton of "
                f"tension should be near the pulley radius ({self.pulley_radius_m:g} m); check the units "
                "and signs of motor_torque_nm and tension_n"
            )
        return fit

    def _check_scale(self, raising_slope_m: float, lowering_slope_m: float) -> None:
        """Refuse lines whose scale no transmission explains: wrong units, or a torque that did not move.

        Under the single-bend law sqrt(m_raise·m_lower) = R/c (R the pulley radius, c the true over the
        assumed torque constant; the paper's supplement, eq. S5), whatever the friction. c is uncertain
        by ±15 % (CubeMars AK60-6 data: 0.068–0.087 Nm/A), so a ratio beyond 2 either way is a unit or
        recording error, not friction.
        """
        ratio = math.sqrt(raising_slope_m * lowering_slope_m) / self.pulley_radius_m
        if 1.0 / MAX_SLOPE_SCALE <= ratio <= MAX_SLOPE_SCALE:
            return
        hint = next(
            (text for factor, text in _UNIT_FACTORS if abs(ratio / factor - 1.0) < 0.1),
            "check the units of motor_torque_nm (Nm) and tension_n (N), and that the motor torque "
            "varies with the load",
        )
        raise FitError(
            f"the lines' slopes ({1e3 * raising_slope_m:.4g} and {1e3 * lowering_slope_m:.4g} mm) are "
            f"{ratio:.3g}× what a {1e3 * self.pulley_radius_m:g} mm pulley gives (sqrt of their product "
            f"should be near the radius, within a factor {MAX_SLOPE_SCALE:g}): {hint}"
        )

    def fit(self, recording: RecordingInput) -> Self:
        """Identify both lines from a bench recording (object, table, path or list of paths).

        Raises
        ------
        RecordingError
            Unreadable or invalid recording, or too few steady-state samples in a direction.
        FitError
            A fitted line is unusable (degenerate tensions, implausible slope).
        """
        self._validate()
        data = self._as_recording(recording)
        selection = bench_preprocess(data, self.preprocessing)
        fits = {direction: self._fit_direction(selection, direction) for direction in DIRECTIONS}
        self._check_scale(fits[RAISING].slope, fits[LOWERING].slope)
        _check_loadable(fits[RAISING], fits[LOWERING])
        self.recording_ = data
        self.selection_ = selection
        self.raising_fit_ = fits[RAISING]
        self.lowering_fit_ = fits[LOWERING]
        self.summary_: IdentificationSummary = identification_summary(
            fits[RAISING], fits[LOWERING], pulley_radius_m=self.pulley_radius_m, thresholds=self.thresholds
        )
        self.model_ = CompensationModel(
            raising=_line(fits[RAISING]),
            lowering=_line(fits[LOWERING]),
            blend_velocity_01_rad_s=float(self.blend_velocity_01_rad_s),
            blend_velocity_99_rad_s=float(self.blend_velocity_99_rad_s),
            pulley_radius_m=float(self.pulley_radius_m),
            raising_fit=_stats(fits[RAISING]),
            lowering_fit=_stats(fits[LOWERING]),
            provenance=self._provenance(data),
        )
        self.dynamic_: DynamicIdentification | None = None
        self.dynamic_error_: str | None = None
        if self.dynamic:
            try:
                latency = float(self.imu_latency_s)
                self.dynamic_ = identify_dynamic(selection, self.model_, imu_latency_s=latency)
            except FitError as error:
                self.dynamic_error_ = str(error)
            else:
                self.model_ = replace(self.model_, dynamic=self.dynamic_.dynamic)
        return self

    def _provenance(self, data: BenchRecording) -> Provenance:
        settings = self.preprocessing
        labels = settings.criterion_labels()
        notes = (
            f"zero-phase Butterworth order {settings.filter_order} low-pass at {settings.cutoff_hz:g} Hz "
            f"per continuous segment; steady state: {'; '.join(labels.values())}; "
            f"robustfit bisquare tune {self.tune:g} (MATLAB-equal); "
            f"raising R² fitlm-robust {self.raising_fit_.r_squared_fitlm_robust:.4f}, "
            f"lowering {self.lowering_fit_.r_squared_fitlm_robust:.4f}"
        )
        return Provenance(
            source_files=tuple(source.path for source in data.sources),
            source_sha256=tuple(source.sha256 for source in data.sources),
            created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
            tool="bowden identify",
            tool_version=__version__,
            notes=notes,
        )

    def _check_fitted(self) -> CompensationModel:
        model = getattr(self, "model_", None)
        if not isinstance(model, CompensationModel):
            raise FitError("this TransmissionIdentifier is not fitted yet; call fit(recording) first")
        return model

    def predict(self, tension_n: ArrayLike, elevation_velocity_rad_s: ArrayLike) -> NDArray[np.float64]:
        """Motor torque, Nm, the identified model commands for these tensions and elevation velocities."""
        model = self._check_fitted()
        tension, velocity = np.broadcast_arrays(
            np.asarray(tension_n, dtype=np.float64), np.asarray(elevation_velocity_rad_s, dtype=np.float64)
        )
        out = np.empty(tension.shape)
        for index, (t, v) in enumerate(zip(tension.ravel(), velocity.ravel(), strict=True)):
            out.flat[index] = model.torque_nm(float(t), float(v))
        return out

    def with_notes(self, notes: str) -> CompensationModel:
        """The fitted model with ``notes`` appended to its provenance (e.g. the bench's name)."""
        model = self._check_fitted()
        provenance = model.provenance or Provenance()
        joined = f"{provenance.notes}; {notes}" if provenance.notes else notes
        return replace(model, provenance=replace(provenance, notes=joined))


def _line(fit: RobustFit) -> CompensationLine:
    return CompensationLine(intercept_nm=fit.intercept, slope_m=fit.slope)


def _stats(fit: RobustFit) -> LineFitStats:
    return LineFitStats(
        n=fit.n,
        r_squared_ols=fit.r_squared_ols,
        r_squared_robust=fit.r_squared_fitlm_robust,
        robust_scale_nm=fit.scale,
        intercept_se_nm=fit.intercept_se,
        slope_se_m=fit.slope_se,
    )
