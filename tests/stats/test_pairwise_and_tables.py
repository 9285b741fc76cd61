"""Holm adjustment, pairwise contrasts and the paper-like tables."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd
import pytest
from statsmodels.stats.multitest import multipletests

from bowden.errors import ParameterError
from bowden.stats import (
    GammaGlmmDesign,
    GlmmResult,
    analyse_outcome,
    change_colour,
    effects_table,
    estimated_marginal_means,
    format_p,
    holm_adjust,
    pairwise_comparisons,
    pairwise_table,
    significance_code,
    significance_html,
    significance_styler,
    significance_table,
    simulate_gamma_glmm,
    type_iii_tests,
)

Fitter = Callable[[str, str], GlmmResult]


def test_holm_matches_statsmodels() -> None:
    p = np.random.default_rng(0).uniform(0, 0.2, size=15) ** 2
    np.testing.assert_allclose(holm_adjust(p), multipletests(p, method="holm")[1], rtol=1e-15)
    assert holm_adjust([]).size == 0
    with pytest.raises(ParameterError):
        holm_adjust([0.1, 1.2])


def test_reverse_flips_the_sign_and_keeps_p(fitted: Fitter) -> None:
    fit = fitted("balanced", "pql-reml")
    forward = pairwise_comparisons(fit, "condition")
    backward = pairwise_comparisons(fit, "condition", reverse=True)
    assert backward["contrast"].iloc[0] == "pretension - no_suit"
    np.testing.assert_allclose(backward["estimate"], -forward["estimate"])
    np.testing.assert_allclose(backward["p_holm"], forward["p_holm"])
    np.testing.assert_allclose(backward["ratio"], 1.0 / forward["ratio"])


def test_contrasts_are_differences_of_the_marginal_means(fitted: Fitter) -> None:
    fit = fitted("unbalanced", "pql-reml")
    emm = estimated_marginal_means(fit, "speed").set_index("speed")["mean"]
    pairs = pairwise_comparisons(fit, "speed")
    for _, row in pairs.iterrows():
        assert row["estimate"] == pytest.approx(emm[row["level_a"]] - emm[row["level_b"]], rel=1e-12)
        assert row["percent_change"] == pytest.approx(100 * (emm[row["level_a"]] / emm[row["level_b"]] - 1))


def test_type_iii_f_is_wald_over_df(fitted: Fitter) -> None:
    fit = fitted("balanced", "pql-reml")
    res = type_iii_tests(fit)
    asym = type_iii_tests(fit, df_method="asymptotic")
    np.testing.assert_allclose(res["F"] * res["df1"], res["chisq"])
    assert (res["df2"] == fit.residual_df).all() and np.isinf(asym["df2"]).all()
    # With 1824 denominator df the F and chi-square p-values nearly coincide.
    np.testing.assert_allclose(res["p"], asym["p"], rtol=0.05)
    with pytest.raises(ParameterError):
        type_iii_tests(fit, df_method="satterthwaite")  # type: ignore[arg-type]


def test_format_and_codes() -> None:
    assert format_p(0.0004) == "< 0.001" and format_p(0.0231) == "0.023" and format_p(1.0) == "1.000"
    assert [significance_code(p) for p in (0.0009, 0.001, 0.049, 0.05)] == ["**", "*", "*", ""]
    assert change_colour(-60.0) == "rgb(0,255,0)" and change_colour(60.0) == "rgb(255,0,0)"
    assert change_colour(0.0) == "rgb(255,255,255)"
    assert change_colour(-30.0, full_scale_percent=60.0) == "rgb(127,255,127)"  # round(127.5) = 128 -> 127


@pytest.fixture(scope="module")
def analyses() -> list:  # type: ignore[type-arg]
    strong = GammaGlmmDesign(condition_effect=(0.0, -0.15, -0.25, -0.35))
    flat = GammaGlmmDesign(condition_effect=(0.0,) * 4, interaction=((0.0,) * 3,) * 4)
    return [
        analyse_outcome(simulate_gamma_glmm(strong, seed=20), "Ant. delt."),
        analyse_outcome(simulate_gamma_glmm(flat, seed=21), "Null"),
    ]


def test_effects_table_shows_participant_means_and_p_values(analyses: list) -> None:  # type: ignore[type-arg]
    table = effects_table(analyses)
    assert list(table.columns) == ["no", "pre", "25%", "50%", "p (C)", "p (V)", "p (C x V)"]
    data = analyses[0].data
    cell = (
        data[(data.condition == "support_25") & (data.speed == "V2")].groupby("participant")["value"].mean()
    )
    assert table.loc[("Ant. delt.", "V2"), "25%"] == f"{cell.mean():.3f} ({cell.std():.3f})"
    assert table.loc[("Ant. delt.", "V1"), "p (C)"] == format_p(
        float(analyses[0].tests.loc["condition", "p"])
    )
    se = effects_table(analyses, spread="se").loc[("Ant. delt.", "V2"), "25%"]
    assert se == f"{cell.mean():.3f} ({cell.std() / np.sqrt(17):.3f})"


def test_pairwise_table_is_na_without_a_significant_effect(analyses: list) -> None:  # type: ignore[type-arg]
    assert analyses[0].tests.loc["condition", "p"] < 0.05 < analyses[1].tests.loc["condition", "p"]
    table = pairwise_table(analyses)
    assert list(dict.fromkeys(c for c, _ in table.columns)) == [
        "pre-no",
        "25%-no",
        "50%-no",
        "25%-pre",
        "50%-pre",
        "50%-25%",
    ]
    assert (table.loc["Null"] == "N/A").all()
    row = analyses[0].condition_pairs.iloc[2]
    assert table.loc["Ant. delt.", ("50%-no", "p")] == format_p(row["p_holm"])
    assert table.loc["Ant. delt.", ("50%-no", "percent")] == f"{row['percent_change']:.1f}"
    speeds = pairwise_table(analyses, factor="speed", only_if_significant=False)
    assert list(dict.fromkeys(c for c, _ in speeds.columns)) == ["V1-V2", "V1-V3", "V2-V3"]


def test_significance_colour_table(analyses: list) -> None:  # type: ignore[type-arg]
    table = significance_table(analyses)
    pct = float(table.loc["Ant. delt.", ("50%-no", "percent")])
    p = float(table.loc["Ant. delt.", ("50%-no", "p")])
    fragment = significance_html(table, caption="Raising phase")
    assert fragment.startswith("<table") and "<caption>Raising phase</caption>" in fragment
    assert f"background:{change_colour(pct)}" in fragment
    assert f">{significance_code(p)}</td>" in fragment
    pytest.importorskip("jinja2")  # pandas' Styler needs it (comes with the dev extra via distributed)
    styled = significance_styler(table).to_html()
    assert change_colour(pct) in styled
    assert isinstance(table, pd.DataFrame) and table.shape == (2, 12)
    # The paper's gate: no stars for an outcome whose condition term is not significant (p >= 0.05).
    assert analyses[1].tests.loc["condition", "p"] >= 0.05
    null_p = table.loc["Null", [(c, "p") for c, _ in table.columns[::2]]].to_numpy(dtype=float)
    assert np.isnan(null_p).all()
    ungated = significance_table(analyses, only_if_significant=False)
    ungated_p = ungated.loc["Null", [(c, "p") for c, _ in ungated.columns[::2]]].to_numpy(dtype=float)
    assert np.isfinite(ungated_p).all()
