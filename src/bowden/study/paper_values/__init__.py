"""The paper's published numbers, to print beside what a simulated (or real) study reproduces.

Source: ``shared/paper/sensorless-tension-control.tex``. Every table the paper publishes as numbers is
here, cited by its LaTeX label: Table 1 and Supplementary Tables S1-S3 (:mod:`.tracking`), S4-S6
(:mod:`.kinematics`), S7-S12 and the colour Tables 2, 3 and tab:iEMG_deltas_visual (:mod:`.iemg`), and
the questionnaire p-values of the Results text (:mod:`.questionnaires`). The ``*_data`` modules are
generated from the LaTeX by ``scripts/extract_paper_values.py``; p-values are :class:`P` (a printed
"< 0.001" is an upper bound and says so).
"""

from bowden.study.paper_values.iemg import iemg_colours, iemg_means, iemg_p, iemg_pairs
from bowden.study.paper_values.kinematics import (
    KINEMATICS_P_VALUES,
    kinematic_pairs,
    kinematics,
    kinematics_p,
)
from bowden.study.paper_values.pvalue import P
from bowden.study.paper_values.questionnaires import nordic_pairs, questionnaire_p, questionnaire_results
from bowden.study.paper_values.tracking import (
    peak_percent_error,
    percent_error_rmse,
    tension_rmse_n,
    torque_rmse_nm,
)

__all__ = [
    "KINEMATICS_P_VALUES",
    "P",
    "iemg_colours",
    "iemg_means",
    "iemg_p",
    "iemg_pairs",
    "kinematic_pairs",
    "kinematics",
    "kinematics_p",
    "nordic_pairs",
    "peak_percent_error",
    "percent_error_rmse",
    "questionnaire_p",
    "questionnaire_results",
    "tension_rmse_n",
    "torque_rmse_nm",
]
