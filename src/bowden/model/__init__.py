"""Physics and biomechanics: transmission laws, anthropometry, cuff geometry, gravity assistance and
the compensation (inverse transmission) model. Pure functions and frozen dataclasses; the only I/O
is reading and writing ``model.json``.
"""

from bowden.model.anthropometry import (
    STANDARD_GRAVITY_M_S2,
    ArmModel,
    ArmSegment,
    Subject,
    arm_gravity_torque_nm,
    arm_model,
)
from bowden.model.assistance import (
    PRETENSION,
    AssistanceParameters,
    desired_joint_torque_nm,
    desired_tension_n,
)
from bowden.model.compensation import CompensationModel, Provenance
from bowden.model.geometry import CuffGeometry
from bowden.model.lines import CompensationLine, LineFitStats

__all__ = [
    "PRETENSION",
    "STANDARD_GRAVITY_M_S2",
    "ArmModel",
    "ArmSegment",
    "AssistanceParameters",
    "CompensationLine",
    "CompensationModel",
    "CuffGeometry",
    "LineFitStats",
    "Provenance",
    "Subject",
    "arm_gravity_torque_nm",
    "arm_model",
    "desired_joint_torque_nm",
    "desired_tension_n",
]
