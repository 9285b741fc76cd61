"""Statistics of the paper: gamma GLMM, Type-III tests, Holm pairwise comparisons, Friedman, tables.

Outcomes (iEMG, elevation RMSE, SPARC) are modelled as in the paper's SPSS GENLINMIXED analysis: gamma
family, log link, condition x speed fixed effects, a random intercept per participant, fitted by
linearised pseudo-likelihood with REML (or by maximum likelihood, Laplace or adaptive quadrature).
Questionnaire scores get Friedman's test with MATLAB's Bonferroni post-hoc.

Input is a tidy DataFrame with columns ``participant, condition, speed, value`` (names configurable).

>>> from bowden.stats import analyse_outcome, simulate_gamma_glmm, effects_table
>>> result = analyse_outcome(simulate_gamma_glmm(seed=3), "iEMG")
>>> list(result.tests.index)
['condition', 'speed', 'condition:speed']
"""

from bowden.stats.analysis import AnalysisOptions, OutcomeAnalysis, analyse_outcome
from bowden.stats.friedman import FriedmanResult, friedman, friedman_multcompare, friedman_test
from bowden.stats.glmm import GlmmOptions, GlmmResult, fit_gamma_glmm
from bowden.stats.pairwise import holm_adjust, pairwise_comparisons
from bowden.stats.synthetic import GammaGlmmDesign, simulate_gamma_glmm
from bowden.stats.tables import (
    change_colour,
    effects_table,
    format_p,
    pairwise_table,
    significance_code,
    significance_html,
    significance_styler,
    significance_table,
)
from bowden.stats.tests_of_effects import estimated_marginal_means, type_iii_tests

__all__ = [
    "AnalysisOptions",
    "FriedmanResult",
    "GammaGlmmDesign",
    "GlmmOptions",
    "GlmmResult",
    "OutcomeAnalysis",
    "analyse_outcome",
    "change_colour",
    "effects_table",
    "estimated_marginal_means",
    "fit_gamma_glmm",
    "format_p",
    "friedman",
    "friedman_multcompare",
    "friedman_test",
    "holm_adjust",
    "pairwise_comparisons",
    "pairwise_table",
    "significance_code",
    "significance_html",
    "significance_styler",
    "significance_table",
    "simulate_gamma_glmm",
    "type_iii_tests",
]
