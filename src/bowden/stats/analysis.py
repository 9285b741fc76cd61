"""One outcome, analysed as in the paper: GLMM, Type-III tests, pairwise comparisons."""

from __future__ import annotations

from dataclasses import dataclass, field

import pandas as pd

from bowden.errors import ParameterError
from bowden.stats.design import build_design
from bowden.stats.glmm import GlmmOptions, GlmmResult, fit_design
from bowden.stats.pairwise import Family, pairwise_comparisons
from bowden.stats.tests_of_effects import DfMethod, type_iii_tests


@dataclass(frozen=True, kw_only=True)
class AnalysisOptions:
    """How an outcome is analysed.

    Attributes
    ----------
    glmm:
        Fitting options (default: SPSS-like PQL-REML).
    df_method:
        ``"residual"`` (SPSS) or ``"asymptotic"`` degrees of freedom for tests and comparisons.
    family:
        Holm family of the per-speed condition comparisons: ``"by_group"`` (each speed) or
        ``"whole_table"``.
    """

    glmm: GlmmOptions = field(default_factory=GlmmOptions)
    df_method: DfMethod = "residual"
    family: Family = "by_group"

    def __post_init__(self) -> None:
        if self.df_method not in ("residual", "asymptotic"):
            raise ParameterError(f"df_method must be 'residual' or 'asymptotic', got {self.df_method!r}")
        if self.family not in ("by_group", "whole_table"):
            raise ParameterError(f"family must be 'by_group' or 'whole_table', got {self.family!r}")


@dataclass(frozen=True, kw_only=True)
class OutcomeAnalysis:
    """Everything the paper reports for one outcome.

    Attributes
    ----------
    name:
        Outcome label used in tables (e.g. ``"Ant. delt."`` or ``"RMSE (deg)"``).
    data:
        The tidy input (columns renamed to participant, condition, speed, value).
    fit:
        The fitted GLMM.
    tests:
        Type-III tests (:func:`~bowden.stats.type_iii_tests`).
    condition_pairs:
        Conditions pooled over speeds, later minus earlier (the paper's ``pre - no``), Holm.
    speed_pairs:
        Speeds pooled over conditions, earlier minus later (the paper's ``V1 - V2``), Holm.
    condition_pairs_by_speed:
        Conditions within each speed, Holm by ``options.family``.
    """

    name: str
    data: pd.DataFrame = field(repr=False)
    fit: GlmmResult = field(repr=False)
    tests: pd.DataFrame
    condition_pairs: pd.DataFrame
    speed_pairs: pd.DataFrame
    condition_pairs_by_speed: pd.DataFrame = field(repr=False)


def analyse_outcome(
    data: pd.DataFrame,
    name: str = "value",
    *,
    options: AnalysisOptions | None = None,
    participant: str = "participant",
    condition: str = "condition",
    speed: str = "speed",
    value: str = "value",
) -> OutcomeAnalysis:
    """Fit the gamma GLMM to one outcome and compute its tests and pairwise comparisons.

    Parameters
    ----------
    data:
        Tidy table, one row per observation.
    name:
        Label of the outcome in tables.
    options:
        :class:`AnalysisOptions`.
    participant, condition, speed, value:
        Column names.

    Returns
    -------
    OutcomeAnalysis
    """
    options = options or AnalysisOptions()
    design = build_design(data, participant=participant, condition=condition, speed=speed, value=value)
    fit = fit_design(design, options.glmm)
    tidy = pd.DataFrame(
        {
            "participant": data[participant].astype(str).to_numpy(),
            "condition": data[condition].astype(str).to_numpy(),
            "speed": data[speed].astype(str).to_numpy(),
            "value": design.y,
        }
    )
    return OutcomeAnalysis(
        name=name,
        data=tidy,
        fit=fit,
        tests=type_iii_tests(fit, df_method=options.df_method),
        condition_pairs=pairwise_comparisons(fit, "condition", reverse=True, df_method=options.df_method),
        speed_pairs=pairwise_comparisons(fit, "speed", reverse=False, df_method=options.df_method),
        condition_pairs_by_speed=pairwise_comparisons(
            fit, "condition", by="speed", family=options.family, reverse=True, df_method=options.df_method
        ),
    )
