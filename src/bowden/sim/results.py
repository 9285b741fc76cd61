"""Results of simulated trials and cohorts: objects that explain themselves.

A :class:`TrialSimulation` holds one trial's per-cycle signals under the trial-recording names of
``bowden.contracts`` plus what only a simulation knows (true tension and arm state, the muscle torque),
and can make the trial's muscle activations and synthetic sEMG on demand. A
:class:`CohortSimulation` holds all trials of a cohort and the questionnaire answers.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from bowden import contracts as c
from bowden.errors import ParameterError
from bowden.sim.emg import amplitude_factors, emg_synthesize
from bowden.sim.muscles import max_elevation_torque_nm, muscle_activations
from bowden.sim.participants import VirtualParticipant

# Signals only a simulation has (truth), recorded beside the contract's trial columns.
TRUE_TENSION = "true_tension_n"
TRUE_ELEVATION = "true_elevation_rad"
TRUE_ELEVATION_VELOCITY = "true_elevation_velocity_rad_s"
SHOULDER_TORQUE = "shoulder_torque_nm"  # the participant's net muscle torque (> 0 elevates)
CORRECTION_TORQUE = "correction_torque_nm"  # its part countering forces it did not plan for
COCONTRACTION = "cocontraction_nm"  # co-contraction torque on each side of the joint
SHEATH_STUCK = "sheath_stuck"  # 1 while the Bowden sheath sticks
LIMIT_FLAGS = "limit_flags"  # bowden.control.Limit bits of the cycle
TRUTH_SIGNALS = (
    TRUE_TENSION, TRUE_ELEVATION, TRUE_ELEVATION_VELOCITY, SHOULDER_TORQUE, CORRECTION_TORQUE, COCONTRACTION,
    SHEATH_STUCK,
)

SIGNAL_DESCRIPTIONS: Mapping[str, str] = {
    c.TRIAL_REFERENCE_ELEVATION: "reference shown on the screen, rad",
    c.TRIAL_ELEVATION: "IMU elevation (noise, bias; float32), rad",
    c.TRIAL_ELEVATION_VELOCITY: "IMU elevation velocity (noise, bias; float32), rad/s",
    c.TRIAL_DESIRED_TENSION: "controller's desired anchor tension, N (NaN without suit)",
    c.TRIAL_MOMENT_ARM: "controller's moment arm r(θ), m",
    c.TRIAL_COMMANDED_TORQUE: "commanded motor torque, Nm",
    c.TRIAL_MOTOR_TORQUE: "motor-reported torque (12-bit reply field), Nm",
    c.TRIAL_MOTOR_VELOCITY: "spool velocity (12-bit reply field), rad/s",
    c.TRIAL_TENSION: "load-cell tension (noise; 16-bit ADC code), N",
    c.TRIAL_STATE: "loop state (contracts.LOOP_STATE_RUNNING throughout)",
    c.TRIAL_FAULT: "fault bits (bowden.control.Fault)",
    LIMIT_FLAGS: "limit bits (bowden.control.Limit)",
    TRUE_TENSION: "true anchor tension, N",
    TRUE_ELEVATION: "true elevation, rad",
    TRUE_ELEVATION_VELOCITY: "true elevation velocity, rad/s",
    SHOULDER_TORQUE: "participant's net shoulder muscle torque, Nm",
    CORRECTION_TORQUE: "its part countering forces not planned for (feedback + learned), Nm",
    COCONTRACTION: "participant's co-contraction torque on each side of the joint, Nm",
    SHEATH_STUCK: "1 while the sheath sticks",
}


@dataclass(frozen=True, eq=False)
class TrialSimulation:
    """One simulated trial: a participant repeating the reference cycle in one condition and speed.

    Attributes
    ----------
    participant, condition, speed
        Who, which condition (``contracts.CONDITIONS``) and speed (``contracts.SPEEDS``).
    time_s
        Control-cycle times, s (0 at the start of the recording).
    signals
        Named signals, one value per cycle (see :data:`SIGNAL_DESCRIPTIONS`).
    movement_start_s, movement_duration_s, repetitions
        The reference rests at its low point until ``movement_start_s`` and then makes
        ``repetitions`` raise-and-lower cycles, each movement lasting ``movement_duration_s``.
    seed
        Seed of this trial's noise (also seeds its sEMG).
    """

    participant: VirtualParticipant
    condition: str
    speed: str
    time_s: NDArray[np.float64]
    signals: Mapping[str, NDArray[np.float64]]
    movement_start_s: float
    movement_duration_s: float
    repetitions: int
    seed: int
    _cache: dict[str, object] = field(default_factory=dict, repr=False)

    def __repr__(self) -> str:
        return (
            f"TrialSimulation({self.participant.participant_id}, {self.condition}, {self.speed}: "
            f"{self.time_s.size} cycles over {self.duration_s:.1f} s, {self.repetitions} repetitions "
            f"of {2 * self.movement_duration_s:.2f} s from t = {self.movement_start_s:.1f} s; "
            f"signals {', '.join(self.signals)})"
        )

    @property
    def duration_s(self) -> float:
        return float(self.time_s[-1] - self.time_s[0]) if self.time_s.size else 0.0

    @property
    def wears_suit(self) -> bool:
        return self.condition != c.CONDITION_NO_SUIT

    def __getitem__(self, name: str) -> NDArray[np.float64]:
        try:
            return self.signals[name]
        except KeyError:
            raise KeyError(f"no signal {name!r}; signals are {', '.join(self.signals)}") from None

    def repetition_index(self) -> NDArray[np.int64]:
        """Repetition number (0-based) of each cycle, −1 outside the movement."""
        period = 2.0 * self.movement_duration_s
        rel = (self.time_s - self.movement_start_s) / period
        index = np.floor(rel).astype(np.int64)
        index[(rel < 0) | (index >= self.repetitions)] = -1
        return index

    def cycle_fraction(self) -> NDArray[np.float64]:
        """Normalised time within the repetition, 0–1 (raising in [0, 0.5), lowering after), NaN outside."""
        period = 2.0 * self.movement_duration_s
        rel = (self.time_s - self.movement_start_s) / period
        out = rel - np.floor(rel)
        out[self.repetition_index() < 0] = np.nan
        return out

    def to_pandas(self) -> pd.DataFrame:
        """One row per control cycle: ``time_s`` then every signal."""
        frame = pd.DataFrame({c.TRIAL_TIME: self.time_s, **self.signals})
        for name in (c.TRIAL_STATE, c.TRIAL_FAULT, LIMIT_FLAGS):
            frame[name] = frame[name].astype(np.int64)
        return frame

    def activations(self) -> pd.DataFrame:
        """Muscle activations (0–1) per control cycle: ``time_s`` and ``contracts.MUSCLES``."""
        cached = self._cache.get("activations")
        if isinstance(cached, pd.DataFrame):
            return cached
        rate = 1.0 / float(self.time_s[1] - self.time_s[0])
        if self.participant.muscles == "musculoskeletal":
            from bowden.sim.musculoskeletal.trial import trial_activations  # needs the msk extra

            act = trial_activations(
                self.participant, self.signals, sample_rate_hz=rate, elevation=TRUE_ELEVATION,
                velocity=TRUE_ELEVATION_VELOCITY, tension=TRUE_TENSION, correction=CORRECTION_TORQUE,
                cocontraction=COCONTRACTION,
            )
        else:
            act = muscle_activations(
                self.signals[SHOULDER_TORQUE],
                self.signals[TRUE_ELEVATION],
                self.signals[TRUE_ELEVATION_VELOCITY],
                sample_rate_hz=rate,
                max_torque_nm=max_elevation_torque_nm(self.participant.subject.mass_kg),
                correction_torque_nm=self.signals.get(CORRECTION_TORQUE),
                cocontraction_nm=self.signals.get(COCONTRACTION),
            )
        frame = pd.DataFrame(act, columns=list(c.MUSCLES))
        frame.insert(0, c.TRIAL_TIME, self.time_s)
        self._cache["activations"] = frame
        return frame

    def emg_amplitude_factors(self) -> NDArray[np.float64]:
        """The sEMG amplitude factors per control cycle and muscle: the trial's times each
        repetition's (:func:`bowden.sim.emg.amplitude_factors`), drawn from the trial's seed."""
        p = self.participant
        return amplitude_factors(
            self.repetition_index(), trial_sd=p.emg_trial_sd, repetition_sd=p.emg_repetition_sd,
            seed=self.seed,
        )

    def emg(self, rate_hz: float = c.EMG_RATE_HZ) -> pd.DataFrame:
        """Synthetic raw sEMG (V): ``time_s`` and ``contracts.MUSCLES`` at ``rate_hz`` (paper: 2 kHz)."""
        act = self.activations()
        p = self.participant
        return emg_synthesize(
            act[c.TRIAL_TIME].to_numpy(),
            act[list(c.MUSCLES)].to_numpy(),
            gains=p.emg_gains,
            heart_rate_bpm=p.heart_rate_bpm,
            ecg_amplitude=p.ecg_amplitude,
            seed=self.seed + 7919,
            rate_hz=rate_hz,
            factors=self.emg_amplitude_factors(),
        )


@dataclass(frozen=True, eq=False)
class CohortSimulation:
    """All simulated trials of a cohort and their questionnaire answers.

    Attributes
    ----------
    participants
        The virtual cohort.
    trials
        Every trial, ordered by participant, then condition order, then speed.
    condition_orders
        Per participant id, the order its conditions were run in (no suit first, others shuffled).
    questionnaires
        Long table: ``participant_id, condition, questionnaire, item, score``.
    """

    participants: tuple[VirtualParticipant, ...]
    trials: tuple[TrialSimulation, ...]
    condition_orders: Mapping[str, tuple[str, ...]]
    questionnaires: pd.DataFrame

    def __repr__(self) -> str:
        simulated = sum(t.duration_s for t in self.trials)
        return (
            f"CohortSimulation({len(self.participants)} participants, {len(self.trials)} trials, "
            f"{simulated:.0f} s simulated, {len(self.questionnaires)} questionnaire answers)"
        )

    def __iter__(self) -> Iterator[TrialSimulation]:
        return iter(self.trials)

    def trial(self, participant_id: str, condition: str, speed: str) -> TrialSimulation:
        for t in self.trials:
            if (t.participant.participant_id, t.condition, t.speed) == (participant_id, condition, speed):
                return t
        raise ParameterError(f"no trial for {participant_id!r}, {condition!r}, {speed!r}")

    def to_pandas(self) -> pd.DataFrame:
        """Every trial's cycles, with ``participant_id``, ``condition`` and ``speed`` columns first."""
        frames = []
        for t in self.trials:
            frame = t.to_pandas()
            frame.insert(0, "speed", t.speed)
            frame.insert(0, "condition", t.condition)
            frame.insert(0, "participant_id", t.participant.participant_id)
            frames.append(frame)
        return pd.concat(frames, ignore_index=True)


def phase_masks(trial: TrialSimulation, *, drop_first: bool = True) -> dict[str, NDArray[np.bool_]]:
    """Samples of the entire movement, raising and lowering (the paper drops the first repetition)."""
    rep = trial.repetition_index()
    frac = trial.cycle_fraction()
    inside = rep >= (1 if drop_first else 0)
    return {"entire": inside, "raising": inside & (frac < 0.5), "lowering": inside & (frac >= 0.5)}


def rmse(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    d = a - b
    return math.sqrt(float(np.mean(d * d))) if d.size else math.nan
