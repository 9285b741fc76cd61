"""Virtual participants: a cohort drawn like the paper's, each with arm dynamics and a human controller.

The paper's cohort (Results): 17 adults analysed, 12 women and 5 men, stature 1.70 ± 0.11 m, body
mass 63.23 ± 11.51 kg, age 29.33 ± 7.04 years. :func:`generate_cohort` draws statures by sex and body
mass from a body-mass index, then matches the sample's mean and standard deviation to the paper's, so
every seed gives a cohort with the paper's summary statistics and different individuals.

Each participant moves its arm with the controller of :func:`bowden.sim._kernels.human_torque`:
feedforward from an imperfect internal model of its own arm minus the assistance it expects from
the suit, an impedance about the intended movement stiffened by co-contraction, what it learns of the
suit's forces, a practised and wandering visuomotor lag and force-dependent noise. Its corrections
are made by the muscles that oppose the force (:mod:`bowden.sim.muscles`; docs/simulation.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from bowden.contracts import MUSCLES
from bowden.errors import ParameterError
from bowden.model import STANDARD_GRAVITY_M_S2, Subject, arm_model
from bowden.protocol.minimum_jerk import MinimumJerkCycle
from bowden.sim import _kernels as k
from bowden.sim.parameters import ArmParameters, check_seed

# Paper, Results: cohort summary statistics.
PAPER_COHORT_SIZE = 17
PAPER_COHORT_FEMALE = 12
PAPER_HEIGHT_M = (1.70, 0.11)
PAPER_MASS_KG = (63.23, 11.51)
PAPER_AGE_YEARS = (29.33, 7.04)

# Between-wearer spread of the sheath friction (log-normal SD of ``sheath_friction_scale``). The
# controller is identified once, on the mannequin; each wearer's body routes the sheath differently.
# The paper's own table shows the signature of such a per-wearer gain error: its 50 % support RMSE
# exceeds the pretension RMSE, in quadrature, by the same 5.1-5.5 N in all six speed x direction
# cells (sqrt(RMSE_50^2 - RMSE_pre^2)), i.e. an error proportional to the load that depends on neither
# speed nor direction. 0.3 is a wrap angle that differs by about +-30 % between bodies (k ~ mu*Phi/2);
# no measurement of the paper's suit exists, docs/simulation.md shows the effect of the value.
WEARER_FRICTION_LOG_SD = 0.3
# sEMG amplitude from one trial (block) to the next within a session, per muscle (log-normal SD):
# electrode-skin impedance drifts as the skin sweats, the electrode shifts over the muscle, the
# participant's posture and strategy change between blocks. Nordander et al. 2004 (J Electromyogr
# Kinesiol 14:443, "Precision of measurements of physical workload during standardised manual
# handling. Part I") measured the within-subject, between-day CV of shoulder sEMG amplitude at
# 8 % (trapezius) to 15 % (infraspinatus); between days includes re-applying the electrodes, which a
# session does not, so the within-session spread is at most that: 0.10, inside their range.
EMG_TRIAL_SD = 0.10
# sEMG amplitude from one repetition to the next within a trial, per muscle (log-normal SD).
# CALIBRATED, NOT EVIDENCE: no published cycle-to-cycle spread of shoulder iEMG in repeated arm
# elevations was found. The value is the dispersion the paper's own GLMMs imply: its condition
# tests of Table S7 (posterior deltoid p = 0.005, biceps 0.006, triceps 0.061, entire cycle) on
# 459 repetitions per condition need phi ~ 0.5 (Var(y) = phi mu^2); a mean-one log-normal factor
# of SD s adds exp(s^2) - 1, so s = 0.63 (chosen on seed 0; the register in
# bowden.study.departures.calibration; docs/simulation.md, "Amplitude variability").
EMG_REPETITION_SD = 0.63
# Sources of the muscle activations (VirtualParticipant.muscles, `bowden study --muscles`).
MUSCLE_MODELS = ("simple", "musculoskeletal")
WEARER_FRICTION_SCALE_RANGE = (0.5, 2.0)


@dataclass(frozen=True, kw_only=True)
class ExpectedAssistance:
    """The assistance a participant expects: the controller's nominal law ``r·max(T_floor, s·τ_g/r)``.

    Parameters
    ----------
    support
        Fraction of the controller's gravity torque (0 for pretension).
    controller_gravity_torque_nm
        The controller's (anthropometric) gravity torque at 90°, Nm.
    floor_tension_n
        Tension floor, or the constant tension of the pretension condition, N.
    """

    support: float
    controller_gravity_torque_nm: float
    floor_tension_n: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.support) and 0.0 <= self.support <= 1.0):
            raise ParameterError(f"ExpectedAssistance.support must be in [0, 1], got {self.support!r}")
        if not (math.isfinite(self.controller_gravity_torque_nm) and self.controller_gravity_torque_nm >= 0):
            raise ParameterError("ExpectedAssistance.controller_gravity_torque_nm must be >= 0")
        if not (math.isfinite(self.floor_tension_n) and self.floor_tension_n >= 0.0):
            raise ParameterError("ExpectedAssistance.floor_tension_n must be >= 0")

    @classmethod
    def for_condition(
        cls,
        support: float | str,
        subject: Subject,
        *,
        hand_load_kg: float = 0.5,
        floor_tension_n: float = 10.0,
        pretension_n: float = 10.0,
    ) -> ExpectedAssistance:
        """The nominal law of a study condition (``support`` a fraction or ``"pretension"``)."""
        gravity = STANDARD_GRAVITY_M_S2 * arm_model(subject, hand_load_kg).total_moment_kg_m
        if support == "pretension":
            return cls(support=0.0, controller_gravity_torque_nm=gravity, floor_tension_n=pretension_n)
        if isinstance(support, str):
            raise ParameterError(f"support must be a fraction or 'pretension', got {support!r}")
        return cls(
            support=float(support), controller_gravity_torque_nm=gravity, floor_tension_n=floor_tension_n
        )


@dataclass(frozen=True, kw_only=True)
class VirtualParticipant:
    """One virtual participant.

    Parameters
    ----------
    participant_id
        Pseudonymous id (``"P01"``...).
    subject, age_years
        Anthropometrics (the controller sees ``subject``).
    hand_load_kg
        Weight held in the hand (paper: 0.5 kg).
    gravity_scale, inertia_scale
        True arm gravity torque and inertia relative to de Leva's prediction (individual variation).
    internal_model_error
        The participant's estimate of its own arm (inertia and gravity) relative to the truth.
    visuomotor_lag_s
        How far the movement trails the shown reference. The paper's tracking RMSE (≈ 4.7°, 8.3°,
        13.5° at 60, 120, 180 °/s peak, supplement Table S4) is what a lag of ≈ 0.115 s gives on its
        minimum-jerk cycle (RMS speed 0.64 × peak); the IMU's own latency (50 ms by default) is part
        of that, so the participant's share is ≈ 65 ms.
    aim_offset_rad, amplitude_gain
        Constant aim error and excursion gain of the intended movement.
    stiffness_nm_rad, damping_nms_rad
        Shoulder impedance about the intended movement (co-contraction; 10–50 Nm/rad during
        reaching, Burdet et al. 2001, Nature 414:446).
    motor_noise_nm, motor_noise_fraction, motor_noise_time_s
        Constant and force-dependent motor noise and its correlation time. Noise grows with the
        force of each side's muscles (Harris & Wolpert 1998, Nature 394:780), but at the few
        percent of maximal force this task needs, the constant part dominates (Jones, Hamilton &
        Wolpert 2002, J Neurophysiol 88:1533); so a suit that halves the torque barely quietens
        the movement, while its tension disturbances roughen it (the paper's SPARC, Table S4).
        Size and correlation time are calibrated to Table S4's no-suit SPARC and its fall at 50 %.
    adaptation_time_s
        Time constant of learning the expected assistance after putting on the suit.
    emg_gains
        Surface-EMG amplitude per muscle (electrode placement, skin, fat), order of contracts.MUSCLES.
    heart_rate_bpm, ecg_amplitude
        Heart rate and ECG artefact amplitude relative to a full activation's sEMG.
    discomfort_sensitivity
        How strongly the participant reports discomfort under cuff pressure (questionnaires), z-score.
    cocontraction_gain, cocontraction_time_s, cocontraction_stiffness_per_nm
        Co-contraction: torque each side of the joint builds per Nm of feedback torque (the size
        of the errors the participant corrects), how fast it builds and relaxes, and the joint
        stiffness it adds per Nm (muscle stiffness grows with force: Hogan 1984, IEEE TAC 29:681).
        Errors raise co-contraction and it decays without them (Franklin et al. 2008, J Neurosci
        28:11165); a suit whose tension departs from what the wearer expects makes such errors.
    learning_cycles
        Time constant, in raise-and-lower cycles, of learning what the feedback keeps correcting
        (feedback-error learning, Kawato et al. 1987) as smooth functions of the intended movement:
        a gravity-like, a friction-like and a viscous-like torque (0: no learning). Force fields of
        this kind are learned movement by movement, a fifth to a third of the error at a time
        (Thoroughman & Shadmehr 2000, Nature 407:742), within tens of movements (Shadmehr &
        Mussa-Ivaldi 1994).
    practice_lag_reduction, practice_trials
        Practice: the lag shrinks by this fraction over the session, with this many trials to
        e-fold, as the participant learns to anticipate the periodic reference (a law of practice,
        Newell & Rosenbloom 1981). The paper always ran no suit first; its pretension trials at V1
        and V2 track better than no suit (supplement Table S4), which a suit cannot do by itself.
    lag_trial_sd
        Log-normal SD of the lag from trial to trial (attention and strategy vary between blocks).
    lag_wander_sd, lag_wander_time_s
        Within a trial the lag wanders slowly (log-normal SD, correlation time), so that no two
        repetitions are tracked alike.
    excursion_repetition_sd
        Log-normal SD of each repetition's excursion about :attr:`amplitude_gain`: people do not
        reach the same peak twice (endpoint variability grows with the movement, Harris & Wolpert
        1998; van Beers, Haggard & Wolpert 2004, J Neurophysiol 91:1050).
    emg_trial_sd, emg_repetition_sd
        Log-normal SDs of mean-one sEMG amplitude factors per muscle, one per trial (block) and one
        per repetition (:func:`bowden.sim.emg.amplitude_factors`): what changes a recorded amplitude
        beyond the muscle's activation (electrode-skin impedance, electrode over the muscle, posture
        and strategy between blocks, recruitment from one repetition to the next). The trial's,
        :data:`EMG_TRIAL_SD`, is from the literature; the repetition's, :data:`EMG_REPETITION_SD`,
        is calibrated (docs/simulation.md, "Amplitude variability").
    muscles
        Where the activations come from: ``"simple"``, the hand-made model of :mod:`bowden.sim.muscles`,
        or ``"musculoskeletal"``, MyoArm's mechanics and static optimisation
        (:mod:`bowden.sim.musculoskeletal.trial`; needs the ``msk`` extra).
    sheath_friction_scale
        The suit's sheath friction on this body relative to the mannequin bench. The sheath's bends
        follow the wearer's back and shoulder, and in the capstan limit ``k ≈ μ·Φ/2`` grows with the
        total wrap angle Φ, so a wearer whose routing bends the sheath 30 % more has ≈ 30 % more
        friction than the bench the controller was identified on (see
        :data:`WEARER_FRICTION_LOG_SD`).
    """

    participant_id: str
    subject: Subject
    age_years: float = 29.0
    hand_load_kg: float = 0.5
    gravity_scale: float = 1.0
    inertia_scale: float = 1.0
    internal_model_error: float = 1.0
    visuomotor_lag_s: float = 0.065
    aim_offset_rad: float = 0.0
    amplitude_gain: float = 1.0
    stiffness_nm_rad: float = 25.0
    damping_nms_rad: float = 2.5
    motor_noise_nm: float = 0.5
    motor_noise_fraction: float = 0.01
    motor_noise_time_s: float = 0.25
    adaptation_time_s: float = 2.0
    emg_gains: tuple[float, ...] = (1.0,) * len(MUSCLES)
    heart_rate_bpm: float = 70.0
    ecg_amplitude: float = 0.3
    discomfort_sensitivity: float = 0.0
    sheath_friction_scale: float = 1.0
    cocontraction_gain: float = 1.0
    cocontraction_time_s: float = 1.5
    cocontraction_stiffness_per_nm: float = 6.0
    learning_cycles: float = 3.0
    practice_lag_reduction: float = 0.05
    practice_trials: float = 4.0
    lag_trial_sd: float = 0.02
    lag_wander_sd: float = 0.3
    lag_wander_time_s: float = 0.5
    excursion_repetition_sd: float = 0.05
    emg_trial_sd: float = EMG_TRIAL_SD
    emg_repetition_sd: float = EMG_REPETITION_SD
    muscles: str = "simple"

    def __post_init__(self) -> None:
        if self.muscles not in MUSCLE_MODELS:
            raise ParameterError(f"muscles must be one of {', '.join(MUSCLE_MODELS)}, got {self.muscles!r}")
        checks = {
            "hand_load_kg": (0.0, 5.0),
            "gravity_scale": (0.5, 1.5),
            "inertia_scale": (0.5, 1.5),
            "internal_model_error": (0.5, 1.5),
            "visuomotor_lag_s": (0.0, 0.5),
            "aim_offset_rad": (-0.3, 0.3),
            "amplitude_gain": (0.7, 1.3),
            "stiffness_nm_rad": (1.0, 200.0),
            "damping_nms_rad": (0.1, 20.0),
            "motor_noise_nm": (0.0, 2.0),
            "motor_noise_fraction": (0.0, 0.5),
            "motor_noise_time_s": (0.005, 1.0),
            "adaptation_time_s": (0.01, 60.0),
            "heart_rate_bpm": (30.0, 200.0),
            "ecg_amplitude": (0.0, 5.0),
            "discomfort_sensitivity": (-5.0, 5.0),
            "age_years": (10.0, 100.0),
            "sheath_friction_scale": (0.3, 2.0),
            "cocontraction_gain": (0.0, 10.0),
            "cocontraction_time_s": (0.05, 60.0),
            "cocontraction_stiffness_per_nm": (0.0, 30.0),
            "learning_cycles": (0.0, 100.0),
            "practice_lag_reduction": (0.0, 0.5),
            "practice_trials": (0.1, 100.0),
            "lag_trial_sd": (0.0, 0.5),
            "lag_wander_sd": (0.0, 0.5),
            "lag_wander_time_s": (0.1, 60.0),
            "excursion_repetition_sd": (0.0, 0.3),
            "emg_trial_sd": (0.0, 1.0),
            "emg_repetition_sd": (0.0, 1.0),
        }
        for name, (low, high) in checks.items():
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and low <= value <= high):
                raise ParameterError(f"VirtualParticipant.{name} = {value!r} is outside [{low}, {high}]")
        if len(self.emg_gains) != len(MUSCLES) or not all(g > 0 for g in self.emg_gains):
            raise ParameterError(f"VirtualParticipant.emg_gains needs {len(MUSCLES)} positive gains")

    def trial_lag_s(self, session_trial: int, draw: float) -> float:
        """The visuomotor lag of the participant's ``session_trial``-th trial (0 = its first).

        ``draw`` is a unit normal draw: the trial's own deviation (:attr:`lag_trial_sd`).
        """
        if session_trial < 0:
            raise ParameterError(f"session_trial must be >= 0, got {session_trial}")
        practice = 1.0 - math.exp(-session_trial / self.practice_trials)
        practised = 1.0 - self.practice_lag_reduction * practice
        return self.visuomotor_lag_s * practised * math.exp(self.lag_trial_sd * draw)

    @property
    def gravity_torque_nm(self) -> float:
        """True gravity torque of arm and hand load at 90°, Nm."""
        model = arm_model(self.subject, self.hand_load_kg)
        return STANDARD_GRAVITY_M_S2 * model.total_moment_kg_m * self.gravity_scale

    @property
    def inertia_kgm2(self) -> float:
        """True moment of inertia of arm and hand load about the shoulder, kg·m²."""
        return arm_model(self.subject, self.hand_load_kg).moment_of_inertia_kg_m2 * self.inertia_scale

    def arm_parameters(self) -> ArmParameters:
        """The arm the suit's cable pulls on (passive joint damping 0.3 Nm·s/rad)."""
        return ArmParameters(
            inertia_kgm2=self.inertia_kgm2,
            gravity_torque_nm=self.gravity_torque_nm,
            damping_nms_rad=0.3,
            min_elevation_rad=0.0,
            max_elevation_rad=math.radians(140.0),
        )


def human_vector(
    participant: VirtualParticipant,
    cycle: MinimumJerkCycle,
    *,
    cycles: int,
    start_s: float,
    expected: ExpectedAssistance | None,
    lag_s: float | None = None,
    excursion_draws: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """The compiled human controller's parameter vector (indices ``H_*`` of the kernels).

    ``lag_s`` is the trial's visuomotor lag (:meth:`VirtualParticipant.trial_lag_s`); None takes the
    participant's own. ``excursion_draws`` (one unit normal draw per repetition, or None: every
    repetition alike) set each repetition's excursion (:attr:`VirtualParticipant.excursion_repetition_sd`).
    """
    if cycles < 0:
        raise ParameterError(f"cycles must be >= 0, got {cycles}")
    draws = np.zeros(0) if excursion_draws is None else np.asarray(excursion_draws, dtype=np.float64)
    if draws.ndim != 1 or (draws.size and draws.size < cycles) or not np.isfinite(draws).all():
        raise ParameterError(f"excursion_draws needs one finite draw per repetition ({cycles})")
    h = np.zeros(k.N_HUMAN + draws.size)
    h[k.N_HUMAN :] = draws
    h[k.H_LAG] = participant.visuomotor_lag_s if lag_s is None else lag_s
    h[k.H_OFFSET] = participant.aim_offset_rad
    h[k.H_AMPLITUDE] = participant.amplitude_gain
    h[k.H_INERTIA_EST] = participant.inertia_kgm2 * participant.internal_model_error
    h[k.H_GRAVITY_EST] = participant.gravity_torque_nm * participant.internal_model_error
    h[k.H_STIFFNESS] = participant.stiffness_nm_rad
    h[k.H_DAMPING] = participant.damping_nms_rad
    h[k.H_NOISE_CONST] = participant.motor_noise_nm
    h[k.H_NOISE_SIGNAL] = participant.motor_noise_fraction
    h[k.H_NOISE_TAU] = participant.motor_noise_time_s
    h[k.H_REF_LOW] = cycle.low_rad
    h[k.H_REF_HIGH] = cycle.high_rad
    h[k.H_REF_MOVE_S] = cycle.movement_duration_s
    h[k.H_REF_START] = start_s
    h[k.H_REF_CYCLES] = float(cycles)
    if expected is not None:
        h[k.H_EXP_SUPPORT] = expected.support
        h[k.H_EXP_GRAVITY] = expected.controller_gravity_torque_nm
        h[k.H_EXP_FLOOR_N] = expected.floor_tension_n
    h[k.H_EXP_ADAPT_S] = participant.adaptation_time_s
    h[k.H_COCON_GAIN] = participant.cocontraction_gain
    h[k.H_COCON_TIME_S] = participant.cocontraction_time_s
    h[k.H_COCON_STIFFNESS] = participant.cocontraction_stiffness_per_nm
    h[k.H_LEARN_TIME_S] = participant.learning_cycles * cycle.period_s
    h[k.H_LAG_SD] = participant.lag_wander_sd
    h[k.H_LAG_TIME_S] = participant.lag_wander_time_s
    h[k.H_EXCURSION_SD] = participant.excursion_repetition_sd
    return h


def _matched(values: NDArray[np.float64], mean: float, sd: float) -> NDArray[np.float64]:
    """Shift and scale a sample so that its mean and (n − 1) standard deviation are exactly these."""
    centred = values - values.mean()
    spread = centred.std(ddof=1)
    return mean + sd * centred / spread if spread > 0 else np.full_like(values, mean)


def generate_cohort(
    seed: int = 0,
    *,
    n_participants: int = PAPER_COHORT_SIZE,
    n_female: int | None = None,
    height_m: tuple[float, float] = PAPER_HEIGHT_M,
    mass_kg: tuple[float, float] = PAPER_MASS_KG,
    age_years: tuple[float, float] = PAPER_AGE_YEARS,
    wearer_friction_log_sd: float = WEARER_FRICTION_LOG_SD,
    muscles: str = "simple",
    emg_trial_sd: float = EMG_TRIAL_SD,
    emg_repetition_sd: float = EMG_REPETITION_SD,
) -> tuple[VirtualParticipant, ...]:
    """Draw a cohort like the paper's (defaults), reproducibly from ``seed``.

    Statures are drawn by sex (women 1.64 ± 0.07 m, men 1.78 ± 0.07 m), body mass from a body-mass
    index of 22 ± 2.5 kg/m², and then the sample is shifted and scaled to the requested mean and
    standard deviation (so women stay shorter on average and mass stays correlated with stature).
    Individual differences in arm dynamics, movement and EMG are drawn around the defaults of
    :class:`VirtualParticipant`. ``n_female`` defaults to the paper's proportion (12 of 17).
    ``wearer_friction_log_sd`` is the log-normal spread of the sheath friction between wearers
    (:data:`WEARER_FRICTION_LOG_SD`; 0 gives every wearer the bench's friction). ``muscles`` is
    every participant's :attr:`VirtualParticipant.muscles`; it draws nothing, so both muscle models
    get the same cohort. ``emg_trial_sd`` and ``emg_repetition_sd`` are every participant's sEMG
    amplitude spreads (0 and 0: the activations' own iEMG, as a test of the muscles' mechanism wants);
    they draw nothing here either.
    """
    if not (2 <= n_participants <= 500):
        raise ParameterError(f"n_participants must be between 2 and 500, got {n_participants}")
    if n_female is None:  # the paper's proportion of women, 12 in 17
        n_female = round(n_participants * PAPER_COHORT_FEMALE / PAPER_COHORT_SIZE)
    if not (0 <= n_female <= n_participants):
        raise ParameterError(f"n_female must be between 0 and n_participants, got {n_female}")
    if not (0.0 <= wearer_friction_log_sd <= 1.0):
        raise ParameterError(f"wearer_friction_log_sd must be in [0, 1], got {wearer_friction_log_sd}")
    check_seed(seed)
    rng = np.random.default_rng(seed)
    sexes = ["female"] * n_female + ["male"] * (n_participants - n_female)
    order = rng.permutation(n_participants)
    sexes = [sexes[i] for i in order]
    raw_height = np.array([rng.normal(1.64 if s == "female" else 1.78, 0.07) for s in sexes])
    bmi = rng.normal(22.0, 2.5, n_participants)
    heights = np.clip(_matched(raw_height, *height_m), 1.3, 2.1)
    masses = np.clip(_matched(bmi * raw_height**2, *mass_kg), 35.0, 150.0)
    ages = np.clip(_matched(rng.normal(0.0, 1.0, n_participants), *age_years), 18.0, 70.0)
    cohort = []
    for i in range(n_participants):
        sex: Literal["female", "male"] = "female" if sexes[i] == "female" else "male"
        subject = Subject(height_m=float(heights[i]), mass_kg=float(masses[i]), sex=sex)
        cohort.append(
            VirtualParticipant(
                participant_id=f"P{i + 1:02d}",
                subject=subject,
                age_years=float(ages[i]),
                gravity_scale=float(np.clip(rng.normal(1.0, 0.06), 0.8, 1.2)),
                inertia_scale=float(np.clip(rng.normal(1.0, 0.08), 0.75, 1.25)),
                internal_model_error=float(np.clip(rng.normal(1.0, 0.05), 0.85, 1.15)),
                visuomotor_lag_s=float(np.clip(rng.normal(0.065, 0.02), 0.02, 0.14)),
                aim_offset_rad=float(np.clip(rng.normal(0.0, math.radians(1.5)), -0.1, 0.1)),
                amplitude_gain=float(np.clip(rng.normal(1.0, 0.03), 0.9, 1.1)),
                stiffness_nm_rad=float(np.clip(rng.normal(25.0, 5.0), 12.0, 45.0)),
                damping_nms_rad=float(np.clip(rng.normal(2.5, 0.4), 1.2, 4.0)),
                motor_noise_nm=float(np.clip(rng.normal(0.5, 0.1), 0.2, 0.9)),
                motor_noise_fraction=float(np.clip(rng.normal(0.01, 0.005), 0.0, 0.03)),
                adaptation_time_s=float(np.clip(rng.normal(2.0, 0.6), 0.5, 5.0)),
                emg_gains=tuple(float(g) for g in rng.lognormal(0.0, 0.25, len(MUSCLES))),
                heart_rate_bpm=float(np.clip(rng.normal(70.0, 8.0), 50.0, 100.0)),
                ecg_amplitude=float(np.clip(rng.lognormal(math.log(0.3), 0.3), 0.05, 1.5)),
                discomfort_sensitivity=float(np.clip(rng.normal(0.0, 1.0), -3.0, 3.0)),
                sheath_friction_scale=float(
                    np.clip(rng.lognormal(0.0, wearer_friction_log_sd), *WEARER_FRICTION_SCALE_RANGE)
                ),
                muscles=muscles,
                emg_trial_sd=emg_trial_sd,
                emg_repetition_sd=emg_repetition_sd,
            )
        )
    return tuple(cohort)
