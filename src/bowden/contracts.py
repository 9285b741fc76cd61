"""Names shared by every part of bowden: recording columns, study conditions and speeds, muscles.

These are the contracts of docs/design.md written down once. Identification, the runtime recorder, the
simulator, the analysis and the study store all import their column names from here, so a rename
is one edit and a typo is an import error rather than a silently empty column.
"""

from __future__ import annotations

import re
from typing import Final

# --- Bench recording (input of identification), one row per sample -----------------------------
BENCH_TIME: Final = "time_s"
BENCH_MOTOR_TORQUE: Final = "motor_torque_nm"
BENCH_MOTOR_VELOCITY: Final = "motor_velocity_rad_s"
BENCH_TENSION: Final = "tension_n"
BENCH_ELEVATION: Final = "elevation_rad"
BENCH_TRIAL: Final = "trial"  # optional
BENCH_COLUMNS: Final = (
    BENCH_TIME,
    BENCH_MOTOR_TORQUE,
    BENCH_MOTOR_VELOCITY,
    BENCH_TENSION,
    BENCH_ELEVATION,
)

# --- Trial recording, one row per control cycle -------------------------------------------------
TRIAL_TIME: Final = "time_s"
TRIAL_REFERENCE_ELEVATION: Final = "reference_elevation_rad"  # what the display showed
TRIAL_ELEVATION: Final = "elevation_rad"  # measured (IMU)
TRIAL_ELEVATION_VELOCITY: Final = "elevation_velocity_rad_s"
TRIAL_DESIRED_TENSION: Final = "desired_tension_n"  # controller output of the assistance block
TRIAL_MOMENT_ARM: Final = "moment_arm_m"  # r(theta) used by the controller this cycle
TRIAL_COMMANDED_TORQUE: Final = "commanded_torque_nm"  # motor torque sent
TRIAL_MOTOR_TORQUE: Final = "motor_torque_nm"  # motor torque reported
TRIAL_MOTOR_VELOCITY: Final = "motor_velocity_rad_s"
TRIAL_TENSION: Final = "tension_n"  # load cell, NaN when absent
TRIAL_STATE: Final = "controller_state"  # int, one of the LOOP_STATE_* codes below
TRIAL_FAULT: Final = "fault_flags"  # int bit set of bowden.control.Fault
TRIAL_COLUMNS: Final = (
    TRIAL_TIME,
    TRIAL_REFERENCE_ELEVATION,
    TRIAL_ELEVATION,
    TRIAL_ELEVATION_VELOCITY,
    TRIAL_DESIRED_TENSION,
    TRIAL_MOMENT_ARM,
    TRIAL_COMMANDED_TORQUE,
    TRIAL_MOTOR_TORQUE,
    TRIAL_MOTOR_VELOCITY,
    TRIAL_TENSION,
    TRIAL_STATE,
    TRIAL_FAULT,
)

# Codes of the control loop's state in TRIAL_STATE (bowden.runtime.LoopState; never renumber).
LOOP_STATE_RUNNING: Final = 1  # assistance: the controller's torque goes to the motor
LOOP_STATE_RAMPING_DOWN: Final = 2  # a watchdog or a stop request fired: torque ramps to zero
LOOP_STATE_SAFE: Final = 3  # torque zero and motor mode exited

# Trial metadata: the "backend" a trial ran on. Study stores written before these names existed
# say "simulation" for simulated trials, so readers accept both.
BACKEND_SIM: Final = "sim"
BACKEND_CAN: Final = "can"
SIMULATED_BACKENDS: Final = frozenset({BACKEND_SIM, "simulation"})

# Participants are pseudonymous ids only (docs/design.md): 1-4 capital letters then 1-4 digits, such as
# P01 or S007. Digits are required and lower case refused, so a name can never be stored by mistake.
PARTICIPANT_ID_PATTERN: Final = re.compile(r"[A-Z]{1,4}[0-9]{1,4}")


def is_participant_id(text: object) -> bool:
    """Whether ``text`` is a pseudonymous participant id (the whole string, nothing around it)."""
    return isinstance(text, str) and PARTICIPANT_ID_PATTERN.fullmatch(text) is not None


# --- Study design --------------------------------------------------------------------------------
# Conditions in the paper's order; "no_suit" is always first, the others are randomised.
CONDITION_NO_SUIT: Final = "no_suit"
CONDITION_PRETENSION: Final = "pretension"
CONDITION_SUPPORT_25: Final = "support_25"
CONDITION_SUPPORT_50: Final = "support_50"
CONDITIONS: Final = (
    CONDITION_NO_SUIT,
    CONDITION_PRETENSION,
    CONDITION_SUPPORT_25,
    CONDITION_SUPPORT_50,
)
# Short labels used in the paper's tables and figures.
CONDITION_LABELS: Final = {
    CONDITION_NO_SUIT: "no",
    CONDITION_PRETENSION: "pre",
    CONDITION_SUPPORT_25: "25%",
    CONDITION_SUPPORT_50: "50%",
}
# Support fraction per condition (None: no suit worn; "pretension": constant tension).
CONDITION_SUPPORT: Final[dict[str, float | str | None]] = {
    CONDITION_NO_SUIT: None,
    CONDITION_PRETENSION: "pretension",
    CONDITION_SUPPORT_25: 0.25,
    CONDITION_SUPPORT_50: 0.50,
}

# Movement speeds: peak elevation speed of the minimum-jerk reference, deg/s (paper: V1-V3).
SPEEDS: Final = ("V1", "V2", "V3")
SPEED_PEAK_DEG_S: Final = {"V1": 60.0, "V2": 120.0, "V3": 180.0}

# A lab's own conditions and speeds (bowden.protocol.catalogue: say support_70 at 70 % support, V4 at
# 240 deg/s) are named by one rule: a letter, then up to 23 letters, digits or underscores. The
# paper's names follow it too; so does the database's CHECK of the questionnaires table.
PROTOCOL_NAME_PATTERN: Final = re.compile(r"[A-Za-z][A-Za-z0-9_]{0,23}")
PROTOCOL_NAME_RULE: Final = "a letter, then up to 23 letters, digits or underscores (e.g. support_70, V4)"


def is_protocol_name(text: object) -> bool:
    """Whether ``text`` is a condition or speed name by the one rule (the whole string)."""
    return isinstance(text, str) and PROTOCOL_NAME_PATTERN.fullmatch(text) is not None

REPETITIONS_PER_TRIAL: Final = 10
ELEVATION_LOW_DEG: Final = 20.0
ELEVATION_HIGH_DEG: Final = 100.0

# --- Muscles (sEMG channels) in the paper's order ------------------------------------------------
MUSCLES: Final = (
    "anterior_deltoid",
    "medial_deltoid",
    "posterior_deltoid",
    "biceps",
    "triceps",
    "trapezius",
    "latissimus_dorsi",
    "pectoralis_major",
)
# Muscles whose sEMG carries ECG artefacts (paper: ECG removal for these two).
ECG_CONTAMINATED_MUSCLES: Final = ("latissimus_dorsi", "pectoralis_major")
EMG_RATE_HZ: Final = 2000.0

# --- Movement phases -----------------------------------------------------------------------------
PHASES: Final = ("entire", "raising", "lowering")

# --- Questionnaires between conditions (paper: "Questionnaires") --------------------------------
# Item names as stored in the study store's questionnaires table (questionnaire, item, score).
QUESTIONNAIRE_NORDIC: Final = "nordic"  # modified Nordic questionnaire: discomfort 1-7 per body site
QUESTIONNAIRE_BORG_RPE: Final = "borg_rpe"  # Borg rating of perceived exertion 6-20, item "rpe"
QUESTIONNAIRE_FATIGUE: Final = "fatigue"  # perceived fatigue 1-7 per muscle group
QUESTIONNAIRES: Final = (QUESTIONNAIRE_NORDIC, QUESTIONNAIRE_BORG_RPE, QUESTIONNAIRE_FATIGUE)
BORG_RPE_ITEM: Final = "rpe"
# Score ranges (the study store's CHECK, the forms' and the simulation's bounds).
LIKERT_LOW: Final = 1  # nordic and fatigue: 1 (none) to 7 (extreme)
LIKERT_HIGH: Final = 7
BORG_LOW: Final = 6  # Borg RPE 6-20
BORG_HIGH: Final = 20
NORDIC_SITES: Final = (
    "upper_neck", "lower_neck", "right_shoulder", "left_shoulder", "upper_back", "right_upper_arm",
    "left_upper_arm", "right_elbow", "left_elbow", "right_forearm", "left_forearm", "right_wrist_hand",
    "left_wrist_hand", "middle_back", "lower_back", "hips",
)
FATIGUE_SITES: Final = ("pectoralis_major", "deltoids", "trapezius", "biceps", "triceps", "latissimus_dorsi")
