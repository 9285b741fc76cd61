"""The study-like bench segment on the simulated bench: the controller on the mannequin (issue 28).

The mannequin's motor moves the arm along the study's minimum-jerk cycle (20° → 100° → 20° at the
V1–V3 peak speeds) in impedance mode — stiff (300 Nm/rad, 25 Nm·s/rad) about the reference with
its own inertia and gravity fed forward, no lag, no noise — against the gravity-like load of an arm
(the cohort's first participant's, with the hand load), while the tendon driver runs the
*controller* with one compensation; the load cell gives the true tension. Each compensation runs the
same strokes, at each support of the study (pretension, 25 %, 50 %) and V1–V3.
:func:`recommend_compensation` turns the result into the recommendation rule of
docs/dynamic_compensation.md: per (support, speed) cell, the dynamic compensation only where it
beats the paper's in that cell on held-out strokes (every repetition after the first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from bowden import contracts as c
from bowden.control import build_controller
from bowden.model import AssistanceParameters, CompensationModel, arm_model, desired_tension_n
from bowden.model.dynamic import support_label
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim import _batch_kernel as bk
from bowden.sim import _kernels as k
from bowden.sim.parameters import SuitParameters
from bowden.sim.participants import generate_cohort
from bowden.sim.plant import equilibrium_state, pack_parameters

MANNEQUIN_STIFFNESS_NM_RAD = 300.0
MANNEQUIN_DAMPING_NMS_RAD = 25.0
ONSET_WINDOW = (0.45, 0.75)


@dataclass(frozen=True)
class StrokeResult:
    """Tension RMSE (N) against the support law at the true elevation, and the lowering-onset peak (%
    of the reference, repetition-mean curve between 45 % and 75 % of the cycle), held-out repetitions."""

    tension_rmse_n: float
    onset_peak_pct: float


def run_study_segment(model: CompensationModel, suit: SuitParameters, *, compensation: str, speed: str,
                      support: float | str = 0.5, repetitions: int = 4, seed: int = 0) -> StrokeResult:
    """One speed of the study-like segment with ``compensation``; judged on repetitions 2…n."""
    mannequin = generate_cohort(0)[0]
    subject = mannequin.subject
    cycle = MinimumJerkCycle(low_rad=math.radians(c.ELEVATION_LOW_DEG),
                             high_rad=math.radians(c.ELEVATION_HIGH_DEG),
                             peak_speed_rad_s=math.radians(c.SPEED_PEAK_DEG_S[speed]))
    controller = build_controller(
        model=model, support=support, subject=subject, hand_load_kg=0.5,  # type: ignore[arg-type]
        geometry=suit.geometry, compensation=compensation,  # type: ignore[arg-type]
    )
    arm = mannequin.arm_parameters()
    h = np.zeros(k.N_HUMAN)
    h[k.H_AMPLITUDE] = 1.0
    h[k.H_INERTIA_EST] = arm.inertia_kgm2
    h[k.H_GRAVITY_EST] = arm.gravity_torque_nm
    h[k.H_STIFFNESS] = MANNEQUIN_STIFFNESS_NM_RAD
    h[k.H_DAMPING] = MANNEQUIN_DAMPING_NMS_RAD
    h[k.H_NOISE_TAU] = h[k.H_LAG_TIME_S] = h[k.H_COCON_TIME_S] = h[k.H_EXP_ADAPT_S] = 1.0
    h[k.H_REF_LOW], h[k.H_REF_HIGH] = cycle.low_rad, cycle.high_rad
    h[k.H_REF_MOVE_S] = cycle.movement_duration_s
    lead_in = 1.0
    h[k.H_REF_START] = lead_in
    h[k.H_REF_CYCLES] = float(repetitions)
    period, substeps = 0.002, 8
    n = math.ceil((lead_in + repetitions * cycle.period_s + 0.5) / period)
    p = pack_parameters(replace(suit, substep_s=period / substeps), arm)
    x = equilibrium_state(p, cycle.low_rad, 10.0)
    imu, cell = suit.imu, suit.load_cell
    sensors = np.zeros(bk.N_SENSOR)
    sensors[bk.S_IMU_EL_NOISE], sensors[bk.S_IMU_EL_BIAS] = imu.elevation_noise_rad, imu.elevation_bias_rad
    sensors[bk.S_IMU_VEL_NOISE] = imu.velocity_noise_rad_s
    sensors[bk.S_IMU_VEL_BIAS] = imu.velocity_bias_rad_s
    sensors[bk.S_LOAD_NOISE], sensors[bk.S_LOAD_OFFSET] = cell.noise_n, cell.offset_n
    sensors[bk.S_IMU_DELAY_CYCLES] = round(imu.latency_s / period) * 1.0
    rng = np.random.default_rng(seed)
    out = np.empty((n, bk.N_OUT))
    bk.run_trial(x, p, h, bk.controller_vector(controller), bk.controller_state(controller), sensors, True,
                 period, substeps, rng.standard_normal((n, 3)), np.zeros((n * substeps, 2)), out)
    time_s = np.arange(n) * period
    phase = (time_s - lead_in) / cycle.period_s
    held_out = (phase >= 1.0) & (phase < repetitions)
    assistance = AssistanceParameters(
        support=support, floor_tension_n=10.0, pretension_n=10.0  # type: ignore[arg-type]
    )
    body = arm_model(subject, 0.5)
    truth = out[held_out, bk.O_TRUE_ELEVATION]
    reference = np.array([desired_tension_n(float(th), body, suit.geometry, assistance) for th in truth])
    error = out[held_out, bk.O_TENSION] - reference  # the load cell, as on the bench
    fraction = phase[held_out] % 1.0
    percent = 100.0 * error / reference
    bins = np.minimum((fraction * 100).astype(int), 99)
    counts = np.bincount(bins, minlength=100)
    curve = np.bincount(bins, weights=percent, minlength=100) / np.maximum(counts, 1)
    centres = (np.arange(100) + 0.5) / 100
    window = (centres >= ONSET_WINDOW[0]) & (centres <= ONSET_WINDOW[1]) & (counts > 0)
    return StrokeResult(float(np.sqrt(np.mean(error**2))), float(curve[window].max()))


# The supports of the study's conditions the segment runs (pretension, 25 %, 50 %), each at V1-V3.
STUDY_SUPPORTS: tuple[float | str, ...] = ("pretension", 0.25, 0.5)

Cell = tuple[str, str]  # (support label, speed)


def validate_compensations(
    model: CompensationModel, suit: SuitParameters, *, seed: int = 0,
    supports: tuple[float | str, ...] = STUDY_SUPPORTS,
) -> dict[Cell, dict[str, StrokeResult]]:
    """The study-like segment at every support and speed with each compensation the model has:
    (support label, speed) → name → result."""
    names = ("paper", "dynamic") if model.dynamic is not None else ("paper",)
    return {
        (support_label(support), speed): {
            name: run_study_segment(model, suit, compensation=name, speed=speed, seed=seed, support=support)
            for name in names
        }
        for support in supports
        for speed in c.SPEEDS
    }


@dataclass(frozen=True)
class Recommendation:
    """The choice per measured cell, whether dynamic won every cell, and one line why."""

    cells: tuple[tuple[str, str, bool], ...]
    everywhere: bool
    why: str

    def apply(self, model: CompensationModel) -> CompensationModel:
        """``model`` with this recommendation in its dynamic compensation (unchanged without one)."""
        if model.dynamic is None:
            return model
        return replace(model, dynamic=replace(model.dynamic, recommended=self.everywhere,
                                              recommendation=self.why, recommended_cells=self.cells))


def _label(cell: Cell) -> str:
    support, speed = cell
    return f"{support if support == 'pretension' else support + ' %'} {speed}"


def recommendation(results: dict[Cell, dict[str, StrokeResult]]) -> Recommendation:
    """Per (support, speed) cell: dynamic where it beats the paper's in RMSE and onset peak on the
    held-out repetitions of that cell, the paper's lines elsewhere."""
    if any("dynamic" not in by_name for by_name in results.values()):
        return Recommendation((), False, "the model has no dynamic compensation")
    cells, lost = [], []
    for cell, by_name in results.items():
        paper, dynamic = by_name["paper"], by_name["dynamic"]
        wins = (dynamic.tension_rmse_n < paper.tension_rmse_n
                and dynamic.onset_peak_pct < paper.onset_peak_pct)
        cells.append((cell[0], cell[1], wins))
        if not wins:
            lost.append(f"{_label(cell)} ({dynamic.tension_rmse_n:.2f} N / {dynamic.onset_peak_pct:.1f} % "
                        f"vs {paper.tension_rmse_n:.2f} N / {paper.onset_peak_pct:.1f} %)")
    if not lost:
        why = f"the dynamic compensation beats the paper's in RMSE and onset peak in all {len(cells)} cells"
    else:
        why = (f"dynamic in {len(cells) - len(lost)} of {len(cells)} cells; the paper's lines where it does "
               f"not beat them in RMSE and onset peak: {'; '.join(lost)}")
    return Recommendation(tuple(cells), not lost, why)


def recommend_compensation(
    model: CompensationModel, suit: SuitParameters, *, seed: int = 0,
    supports: tuple[float | str, ...] = STUDY_SUPPORTS,
) -> Recommendation:
    """:func:`recommendation` from :func:`validate_compensations`."""
    return recommendation(validate_compensations(model, suit, seed=seed, supports=supports))


# The grid the study-like fit searches: scale on the identified drag and inertia, shift of the lowering
# line's intercept (Nm). Drag and a lower lowering line both release the cable earlier at a turn, which
# the bench's steady strokes cannot show (presliding, capstan friction growing with tension, play).
FIT_DRAG_SCALES = (1.0, 1.4, 1.8)
FIT_INERTIA_SCALES = (1.0, 2.0)
FIT_LOWERING_SHIFTS_NM = (0.0, -0.05)


def study_cost(results: dict[Cell, dict[str, StrokeResult]]) -> float:
    """Mean over speeds of the dynamic compensation's RMSE and onset peak, each relative to the paper's."""
    terms = []
    for by_name in results.values():
        paper, dynamic = by_name["paper"], by_name["dynamic"]
        terms.append(dynamic.tension_rmse_n / max(paper.tension_rmse_n, 1e-6)
                     + max(dynamic.onset_peak_pct, 0.0) / max(paper.onset_peak_pct, 1.0))
    return float(np.mean(terms))


def fit_on_study_segment(
    model: CompensationModel, suit: SuitParameters, *, seed: int = 0, support: float | str = 0.5
) -> CompensationModel:
    """The dynamic compensation refitted on the study-like strokes with the load cell as the target:
    the grid point (drag and inertia scale, lowering-line shift) with the lowest :func:`study_cost`.
    Returns ``model`` unchanged when it has no dynamic compensation."""
    if model.dynamic is None:
        return model
    dynamic = model.dynamic
    paper = {speed: run_study_segment(model, suit, compensation="paper", speed=speed, seed=seed,
                                      support=support) for speed in c.SPEEDS}
    best, best_cost = model, math.inf
    for drag in FIT_DRAG_SCALES:
        for inertia in FIT_INERTIA_SCALES:
            for shift in FIT_LOWERING_SHIFTS_NM:
                candidate = replace(model, dynamic=replace(
                    dynamic,
                    viscous_nm_s_rad=min(1.0, dynamic.viscous_nm_s_rad * drag),
                    inertia_kg_m2=min(0.05, dynamic.inertia_kg_m2 * inertia),
                    lowering=replace(dynamic.lowering, intercept_nm=dynamic.lowering.intercept_nm + shift),
                ))
                results = {
                    (support_label(support), speed): {"paper": paper[speed],
                            "dynamic": run_study_segment(candidate, suit, compensation="dynamic", speed=speed,
                                                         seed=seed, support=support)}
                    for speed in c.SPEEDS
                }
                cost = study_cost(results)
                if cost < best_cost:
                    best, best_cost = candidate, cost
    return best
