"""The GLMM fits against hand-derived invariants and independent computations (no R needed)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import pytest
from scipy import integrate, special
from statsmodels.regression.mixed_linear_model import MixedLM

from bowden.errors import FitError, OutcomeTableError, ParameterError
from bowden.stats import GlmmOptions, GlmmResult, fit_gamma_glmm, simulate_gamma_glmm
from bowden.stats.design import build_design
from bowden.stats.lmm import GroupSums, fit_random_intercept_lmm
from bowden.stats.marginal import MarginalLikelihood

Fitter = Callable[[str, str], GlmmResult]
Loader = Callable[[str], pd.DataFrame]


def _theta(ref: dict[str, Any]) -> np.ndarray:
    beta = ref["coef"] if "coef" in ref else ref["beta"]
    return np.concatenate([beta, [0.5 * np.log(ref["participant_var"]), np.log(ref["dispersion"])]])


def test_quadrature_loglik_matches_r_numerical_integration(
    reference: dict[str, Any], dataset: Loader
) -> None:
    # R integrated each participant's random intercept with stats::integrate at glmmTMB's estimates.
    for name in ("balanced", "unbalanced"):
        ref = reference[name]["marginal_loglik"]
        model = MarginalLikelihood(build_design(dataset(name)), n_nodes=25)
        assert model.loglik(_theta(ref)) == pytest.approx(ref["loglik"], rel=1e-10)


def test_quadrature_integral_of_one_participant_matches_scipy(dataset: Loader) -> None:
    design = build_design(dataset("unbalanced"))
    beta = np.linalg.lstsq(design.x, np.log(design.y), rcond=None)[0]
    theta = np.concatenate([beta, [np.log(0.3), np.log(0.15)]])
    # One participant alone: the design restricted to their rows.
    rows = design.group == 0
    sub = build_design(
        pd.DataFrame(
            {
                "participant": [*(["a"] * int(rows.sum())), "b"],
                "condition": [*np.asarray(design.conditions)[design.condition_index[rows]], "no_suit"],
                "speed": [*np.asarray(design.speeds)[design.speed_index[rows]], "V1"],
                "value": [*design.y[rows], 1.0],
            }
        )
    )
    eta = sub.x[:-1] @ beta
    y = sub.y[:-1]
    nu, sd = 1.0 / 0.15, 0.3

    def integrand(b: float) -> float:
        mu = np.exp(eta + b)
        logf = nu * np.log(nu / mu) + (nu - 1) * np.log(y) - nu * y / mu - special.gammaln(nu)
        return float(np.exp(np.sum(logf) - b * b / (2 * sd * sd)) / np.sqrt(2 * np.pi * sd * sd))

    exact = np.log(integrate.quad(integrand, -3, 3, epsabs=0, epsrel=1e-12, limit=200)[0])
    model = MarginalLikelihood(sub, n_nodes=20)
    per = model.loglik(theta)
    # Subtract the lone second participant's contribution (one row at y = 1, with its own integral).
    eta_b = float(sub.x[-1] @ beta)

    def integrand_b(b: float) -> float:
        mu = np.exp(eta_b + b)
        logf = nu * np.log(nu / mu) - nu / mu - special.gammaln(nu)
        return float(np.exp(logf - b * b / (2 * sd * sd)) / np.sqrt(2 * np.pi * sd * sd))

    exact_b = np.log(integrate.quad(integrand_b, -3, 3, epsabs=0, epsrel=1e-12, limit=200)[0])
    assert per == pytest.approx(exact + exact_b, rel=1e-9)


@pytest.mark.parametrize("n_nodes", [1, 7])
def test_gradient_matches_finite_differences(
    dataset: Loader, reference: dict[str, Any], n_nodes: int
) -> None:
    model = MarginalLikelihood(build_design(dataset("unbalanced")), n_nodes=n_nodes)
    theta = _theta(reference["unbalanced"]["glmmtmb"]) + 0.01  # away from the optimum: non-zero gradient
    grad = model.gradient(theta)
    fd = np.empty_like(theta)
    for k in range(theta.size):
        h = 1e-4
        e = np.zeros_like(theta)
        e[k] = h
        # Fourth-order central difference.
        fd[k] = (
            -model.loglik(theta + 2 * e)
            + 8 * model.loglik(theta + e)
            - 8 * model.loglik(theta - e)
            + model.loglik(theta - 2 * e)
        ) / (12 * h)
    np.testing.assert_allclose(grad, fd, rtol=1e-6, atol=1e-5)


def test_one_node_quadrature_is_laplace(dataset: Loader) -> None:
    data = dataset("balanced")
    laplace = fit_gamma_glmm(data, options=GlmmOptions(method="laplace"))
    agq1 = fit_gamma_glmm(data, options=GlmmOptions(method="agq", n_agq=1))
    np.testing.assert_allclose(agq1.coef, laplace.coef, rtol=0, atol=1e-12)
    assert agq1.loglik == pytest.approx(laplace.loglik, rel=1e-14)


def test_adaptive_quadrature_converges_in_nodes(fitted: Fitter, reference: dict[str, Any]) -> None:
    agq = fitted("balanced", "agq")  # 15 nodes
    model = MarginalLikelihood(agq.design, n_nodes=41)
    theta = np.concatenate([agq.coef, [0.5 * np.log(agq.participant_var), np.log(agq.dispersion)]])
    assert model.loglik(theta) == pytest.approx(agq.loglik, rel=1e-12)
    # The exact likelihood is above the Laplace one here, and the estimates barely move.
    assert agq.loglik > reference["balanced"]["glmmtmb"]["loglik"]
    assert np.max(np.abs(agq.coef - reference["balanced"]["glmmtmb"]["coef"]) / agq.se) < 0.01


def test_lmm_step_matches_statsmodels_mixedlm(dataset: Loader) -> None:
    design = build_design(dataset("unbalanced"))
    sums = GroupSums.of(design.x, design.group, design.n_participants)
    ours = fit_random_intercept_lmm(np.log(design.y), design.x, design.group, sums, method="REML")
    # Powell: statsmodels' default L-BFGS start wanders to a zero variance on these data.
    sm = MixedLM(np.log(design.y), design.x, groups=design.group).fit(reml=True, method="powell")
    np.testing.assert_allclose(ours.beta, np.asarray(sm.fe_params), rtol=1e-6, atol=1e-8)
    assert ours.sigma2 == pytest.approx(sm.scale, rel=1e-6)
    assert ours.participant_var == pytest.approx(float(np.asarray(sm.cov_re)[0, 0]), rel=1e-5)
    assert ours.loglik == pytest.approx(sm.llf, rel=1e-10)


def test_scaling_the_outcome_moves_only_the_intercept(dataset: Loader, fitted: Fitter) -> None:
    base = fitted("balanced", "pql-reml")
    scaled = fit_gamma_glmm(dataset("balanced").assign(value=lambda d: d["value"] * 7.5))
    assert scaled.coef.iloc[0] == pytest.approx(base.coef.iloc[0] + np.log(7.5), abs=1e-9)
    np.testing.assert_allclose(scaled.coef.iloc[1:], base.coef.iloc[1:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(scaled.se, base.se, rtol=1e-8)
    assert scaled.participant_var == pytest.approx(base.participant_var, rel=1e-8)


def test_recovers_the_simulated_truth_on_a_large_study() -> None:
    data = simulate_gamma_glmm(seed=11).pipe(
        lambda d: pd.concat([d, simulate_gamma_glmm(seed=12, participant_prefix="Q")], ignore_index=True)
    )
    fit = fit_gamma_glmm(data)
    assert fit.dispersion == pytest.approx(1 / 9.0, rel=0.08)
    assert np.sqrt(fit.participant_var) == pytest.approx(0.25, rel=0.35)
    # Sum coding: the no_suit coefficient is its log effect minus the mean over conditions, with the
    # interaction averaged over speeds (no_suit's interaction row is zero).
    inter = np.array([[0, 0, 0], [0, 0.02, -0.02], [0, 0.03, 0.01], [0, -0.01, 0.03]])
    cond = np.array([0.0, -0.03, -0.05, -0.08]) + inter.mean(axis=1)
    truth = cond[0] - cond.mean()
    assert fit.coef.iloc[1] == pytest.approx(truth, abs=3 * fit.se.iloc[1])


def test_level_order_follows_contracts_then_data() -> None:
    data = simulate_gamma_glmm(seed=2).sample(frac=1.0, random_state=1)
    design = build_design(data)
    assert design.conditions == ("no_suit", "pretension", "support_25", "support_50")
    other = data.assign(
        condition=data["condition"].map(
            {"no_suit": "B", "pretension": "A", "support_25": "C", "support_50": "D"}
        )
    )
    assert build_design(other).conditions == tuple(dict.fromkeys(other["condition"]))


def test_custom_column_names() -> None:
    data = simulate_gamma_glmm(seed=4).rename(columns={"participant": "id", "value": "iemg"})
    fit = fit_gamma_glmm(data, participant="id", value="iemg")
    assert fit.n_participants == 17


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.drop(columns="speed"), "column 'speed' is missing"),
        (lambda d: d.assign(value=d["value"].where(d.index != 5, 0.0)), "row 5"),
        (lambda d: d.assign(value=d["value"].where(d.index != 7, -1.0)), "> 0"),
        (lambda d: d.assign(value=d["value"].where(d.index != 9, np.nan)), "row 9"),
        (lambda d: d[~((d["condition"] == "pretension") & (d["speed"] == "V2"))], "pretension x V2"),
        (lambda d: d[d["participant"] == "P01"], "at least two levels"),
    ],
)
def test_bad_tables_are_rejected_with_a_clear_message(
    mutate: Callable[[pd.DataFrame], pd.DataFrame], message: str
) -> None:
    with pytest.raises(OutcomeTableError, match=message):
        fit_gamma_glmm(mutate(simulate_gamma_glmm(seed=5)))


def test_non_convergence_is_reported() -> None:
    with pytest.raises(FitError, match="did not converge"):
        fit_gamma_glmm(simulate_gamma_glmm(seed=6), options=GlmmOptions(max_iterations=2))


def test_options_are_validated() -> None:
    with pytest.raises(ParameterError, match="method"):
        GlmmOptions(method="newton")  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="n_agq"):
        GlmmOptions(n_agq=0)
