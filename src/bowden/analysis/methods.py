"""The methods paragraph of the analysis, written from the parameters actually used.

Like NeuroKit's ``emg_methods``: the report states exactly what was done, so that changing a
parameter changes the text and no description can drift from the code.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from bowden.analysis.emg.process import EmgProcessParameters
from bowden.analysis.outcomes import AnalysisInfo, AnalysisParameters
from bowden.analysis.segmentation import SegmentationParameters
from bowden.model import CompensationModel
from bowden.stats.analysis import OutcomeAnalysis

REFERENCES = {
    "burden": "Burden A. (2017). Surface electromyography. In: Payton C.J., Burden A. (eds.), Biomechanical "
    "Evaluation of Movement in Sport and Exercise, 2nd ed. Routledge. (RMS envelope, as cited by the paper.)",
    "butterworth": "Butterworth S. (1930). On the theory of filter amplifiers. Wireless Engineer 7:536–541.",
    "petersen": "Petersen E., Sauer J., Graßhoff J., Rostalski P. (2020). Removing cardiac artifacts from "
    "single-channel respiratory electromyograms. IEEE Access 8:30905–30917.",
    "pan": "Pan J., Tompkins W.J. (1985). A real-time QRS detection algorithm. IEEE Trans Biomed Eng "
    "32(3):230–236.",
    "emken": "Emken J.L., Benitez R., Sideris A., Bobrow J.E., Reinkensmeyer D.J. (2007). Motor adaptation "
    "as "
    "a greedy optimization of error and effort. J Neurophysiol 97(6):3997–4006.",
    "sparc": "Balasubramanian S., Melendez-Calderon A., Roby-Brami A., Burdet E. (2015). On the analysis of "
    "movement smoothness. J NeuroEng Rehabil 12:112.",
    "wiener": "Wiener N. (1949). Extrapolation, Interpolation, and Smoothing of Stationary Time Series. "
    "MIT Press.",
    "mallows": "Mallows C.L. (1973). Some comments on Cp. Technometrics 15(4):661–675.",
    "efron": "Efron B. (2004). The estimation of prediction error: covariance penalties and "
    "cross-validation. J Am Stat Assoc 99(467):619–632.",
    "fritsch": "Fritsch F.N., Carlson R.E. (1980). Monotone piecewise cubic interpolation. SIAM J Numer Anal "
    "17(2):238–246. (PCHIP)",
    "dumouchel": "DuMouchel W.H., O'Brien F.L. (1989). Integrating a robust option into a multiple "
    "regression computing environment. In: Computer Science and Statistics: Proceedings of the 21st "
    "Symposium on the Interface. American Statistical Association. (Bisquare robust regression, "
    "MATLAB robustfit.)",
    "breslow": "Breslow N.E., Clayton D.G. (1993). Approximate inference in generalized linear mixed models. "
    "J Am Stat Assoc 88(421):9–25.",
    "wolfinger": "Wolfinger R., O'Connell M. (1993). Generalized linear mixed models: a pseudo-likelihood "
    "approach. J Stat Comput Simul 48(3–4):233–243.",
    "holm": "Holm S. (1979). A simple sequentially rejective multiple test procedure. Scand J Stat "
    "6(2):65–70.",
    "friedman": "Friedman M. (1937). The use of ranks to avoid the assumption of normality implicit in the "
    "analysis of variance. J Am Stat Assoc 32(200):675–701.",
    "hollander": "Hollander M., Wolfe D.A. (1999). Nonparametric Statistical Methods, 2nd ed. Wiley. "
    "(Comparisons of mean ranks after Friedman's test.)",
}


@dataclass(frozen=True, kw_only=True)
class MethodsText:
    """A methods paragraph and the references it cites, in citation order."""

    paragraph: str
    references: tuple[str, ...]

    def to_markdown(self) -> str:
        """Paragraph, then a numbered reference list."""
        listed = "\n".join(f"{i}. {ref}" for i, ref in enumerate(self.references, start=1))
        return f"{self.paragraph}\n\n**References**\n\n{listed}\n"


@dataclass(frozen=True, kw_only=True)
class StatisticsDone:
    """What the statistics fitted, counted from the fits (not from a plan), for :func:`with_statistics`.

    Attributes
    ----------
    kinematic_outcomes
        Kinematic outcomes modelled, as the text names them (``"elevation RMSE"``, ``"SPARC"``).
    iemg_muscles
        Phase (``"entire"``, ``"raising"``, ``"lowering"``) → muscles whose iEMG was modelled.
    analyses
        Every fitted model (their fitting method and tests are described).
    not_fitted
        Models that could not be fitted (the report's notes name them).
    questionnaire_items, posthoc_items
        Questionnaire items tested by Friedman's test; those compared pairwise (p < 0.05).
    """

    kinematic_outcomes: tuple[str, ...] = ()
    iemg_muscles: dict[str, int] = field(default_factory=dict)
    analyses: tuple[OutcomeAnalysis, ...] = ()
    not_fitted: int = 0
    questionnaire_items: int = 0
    posthoc_items: int = 0


class _Citations:
    """Numbers references in the order they are first cited, after ``given`` (already numbered)."""

    def __init__(self, given: Sequence[str] = ()) -> None:
        self.references: list[str] = list(given)

    def __call__(self, key: str) -> str:
        reference = REFERENCES[key]
        if reference not in self.references:
            self.references.append(reference)
        return f"[{self.references.index(reference) + 1}]"


def _count(n: int, word: str) -> str:
    """``"1 participant"``, ``"17 participants"``."""
    return f"{n} {word}" if n == 1 else f"{n} {word}s"


def methods_text(
    parameters: AnalysisParameters | None = None, info: AnalysisInfo | None = None
) -> MethodsText:
    """Describe the analysis done with ``parameters`` (and, if given, the counts of ``info``)."""
    p = parameters or (info.parameters if info is not None else AnalysisParameters())
    cite = _Citations()
    sentences = []
    if info is not None:
        sentences.append(
            f"Data of {_count(info.n_participants, 'participant')} ({_count(info.n_trials, 'trial')}, "
            f"{_count(info.n_repetitions, 'repetition')}) were analysed."
        )
    sentences += _emg_sentences(p.emg, cite)
    sentences.append(_segmentation_sentence(p.segmentation, info, cite))
    sentences.append(
        "EMG envelopes were normalised to the mean of the per-repetition peaks of the no-suit condition, "
        "separately for each participant, muscle and speed, and integrated over normalised time (iEMG) for "
        "the entire repetition and for each phase."
    )
    sentences.append(
        "Tension and joint-torque tracking (torque = cable tension × moment arm) were quantified by the RMSE "
        "between desired and measured values, and by the RMSE and the signed peak of the per-sample "
        f"percent error (samples with a desired tension ≤ {p.min_reference_tension_n:g} N excluded). "
        "Elevation tracking was quantified by the RMSE between reference and measured elevation, and "
        f"movement smoothness by the spectral arc length (SPARC) {cite('sparc')} of the elevation speed "
        f"|dθ/dt| (zero padding level {p.sparc.padlevel}, cut-off {p.sparc.fc_hz:g} Hz, amplitude threshold "
        f"{p.sparc.amplitude_threshold:g}) for each repetition and each phase."
    )
    return MethodsText(paragraph=" ".join(sentences), references=tuple(cite.references))


def _emg_sentences(emg: EmgProcessParameters, cite: _Citations) -> list[str]:
    """Filter and envelope; then R-peak detection and the cardiac artefact's removal, if done."""
    sentences = [
        f"EMG signals were band-pass filtered with a zero-phase (forward-backward) Butterworth filter "
        f"{cite('butterworth')} of order {emg.filter_order} between {emg.low_hz:g} and {emg.high_hz:g} Hz "
        f"(−6 dB at both cut-offs after the two passes), full-wave rectified, and smoothed with a sliding "
        f"root-mean-square window of {1000.0 * emg.envelope_window_s:g} ms {cite('burden')}."
    ]
    if emg.ecg_removal == "none" or not emg.ecg_channels:
        return sentences
    detect_on = (
        f"the {emg.ecg_reference_channel.replace('_', ' ')} channel"
        if emg.ecg_reference_channel
        else "a 5–30 Hz band-passed copy of each raw channel"
    )
    sentences.append(
        f"R-peaks were detected on {detect_on} with a Pan–Tompkins detector {cite('pan')} "
        f"(refractory period {1000.0 * emg.min_rr_s:g} ms)"
        + (
            f"; of two beats closer than {emg.min_rr_fraction:g} times the median RR interval, the one "
            "less like the median beat was dropped."
            if emg.min_rr_fraction > 0.0
            else "."
        )
    )
    muscles = " and ".join(name.replace("_", " ") for name in emg.ecg_channels)
    if emg.ecg_removal != "adaptive":
        sentences.append(
            f"The cardiac artefact was removed from the {muscles} by template subtraction "
            f"{cite('petersen')}, subtracting at each R-peak the mean of the "
            f"{emg.ecg.template_beats} surrounding beats."
        )
        return sentences
    return sentences + _adaptive_ecg_sentences(emg, muscles, cite)


def _adaptive_ecg_sentences(emg: EmgProcessParameters, muscles: str, cite: _Citations) -> list[str]:
    e = emg.ecg
    sentences = [
        f"The cardiac artefact was removed from the {muscles} by adaptive template subtraction "
        f"{cite('petersen')}: beats were cut at the midpoints between R-peaks, each beat's template was "
        f"the mean of the {e.template_beats} surrounding beats, aligned by cross-correlation "
        f"(±{e.max_shift_samples} samples), its QRS part (R ± {1000.0 * e.qrs_half_width_s:g} ms) was "
        f"stretched by −{e.stretch_samples}…+{e.stretch_samples} samples per side using PCHIP "
        f"interpolation {cite('fritsch')}, P, QRS and T sections were scaled and offset by least "
        f"squares, and the best-fitting variant was subtracted."
    ]
    if e.denoise_template:
        sentences.append(
            "Before fitting, the templates were passed through a Wiener filter whose noise "
            f"spectrum was that of the EMG left after plain template subtraction {cite('wiener')}."
        )
    if e.gate:
        sentences.append(
            "Each wave (P, QRS, T) was subtracted only where it was expected to remove more "
            "artefact than EMG: the fit's expected error, including its search over shifts and "
            f"stretches, was priced by a covariance penalty {cite('mallows')}{cite('efron')} "
            "bootstrapped on synthetic EMG with the channel's spectrum, and the decision was made "
            "per wave type from a straight line in the beats' EMG variance."
        )
    return sentences


_SOURCES = {
    "reference": "the reference trajectory",
    "elevation": "the measured elevation",
    "auto": "the reference trajectory (the measured elevation where no reference was recorded)",
}


def _segmentation_sentence(seg: SegmentationParameters, info: AnalysisInfo | None, cite: _Citations) -> str:
    """What the repetitions were found on (per trial, when the counts are known) and what was dropped."""
    used = {source: n for source, n in (info.segmentation_sources if info else {}).items() if n}
    if set(used) == {"reference", "elevation"}:
        source = (
            f"the reference trajectory ({_count(used['reference'], 'trial')}) or, where no reference was "
            f"recorded, the measured elevation ({_count(used['elevation'], 'trial')})"
        )
    elif len(used) == 1 and next(iter(used)) in _SOURCES:
        source = _SOURCES[next(iter(used))]  # what every trial was segmented on
    else:
        source = _SOURCES[seg.source]  # the setting (no counts given)
    # Said only when it happened: a study of one repetition per trial keeps it (drop_first 0).
    drop = (
        f" The first {'repetition' if seg.drop_first == 1 else f'{seg.drop_first} repetitions'} of each "
        f"trial {'was' if seg.drop_first == 1 else 'were'} excluded to avoid adaptation effects "
        f"{cite('emken')}."
        if seg.drop_first
        else ""
    )
    return (
        f"Repetitions were segmented on {source} and split at the highest elevation into raising and "
        f"lowering phases.{drop} Each repetition was resampled onto a normalised time vector of "
        f"{seg.n_points} points."
    )


def with_statistics(
    methods: MethodsText, *, model: CompensationModel | None = None, statistics: StatisticsDone | None = None
) -> MethodsText:
    """``methods`` followed by the transmission's identification (from ``model``) and the statistics
    (from what was fitted), citations numbered on from ``methods``'."""
    cite = _Citations(methods.references)
    sentences = [methods.paragraph]
    if model is not None:
        sentences += _identification_sentences(model, cite)
    if statistics is not None and statistics.analyses:
        sentences += _glmm_sentences(statistics, cite)
    if statistics is not None and statistics.questionnaire_items:
        sentences.append(_friedman_sentence(statistics, cite))
    return MethodsText(paragraph=" ".join(sentences), references=tuple(cite.references))


def _identification_sentences(model: CompensationModel, cite: _Citations) -> list[str]:
    """The two compensation lines as identified (or as given, without identification statistics)."""
    lines = []
    for name, line, fit in (("raising", model.raising, model.raising_fit),
                            ("lowering", model.lowering, model.lowering_fit)):
        stats = "" if fit is None else f" (n = {fit.n} samples, robust R² = {fit.r_squared_robust:.4f})"
        lines.append(
            f"{name}, torque = {line.intercept_nm:.3f} Nm + {1000.0 * line.slope_m:.2f} mm × tension{stats}"
        )
    if model.raising_fit is not None and model.lowering_fit is not None:
        recorded = model.provenance.notes if model.provenance is not None else ""
        how = (
            "The transmission was identified on the bench: motor torque was regressed on load-cell tension "
            f"by one robust line (bisquare weights {cite('dumouchel')}) per direction of cable motion"
            + (f" (settings as recorded with the model: {recorded})" if recorded else "")
        )
    else:
        how = (
            "The compensation model related motor torque to cable tension by one line per direction of "
            "cable motion (it holds no identification statistics)"
        )
    return [
        f"{how}: {lines[0]}; {lines[1]}.",
        "The controller blended the two lines by a sigmoid of elevation velocity that gives the raising "
        f"line 1 % weight at {model.blend_velocity_01_rad_s:+g} rad/s and 99 % at "
        f"{model.blend_velocity_99_rad_s:+g} rad/s.",
    ]


_GLMM_METHODS = {
    "pql-reml": ("by pseudo-likelihood with REML, as SPSS GENLINMIXED", ("wolfinger", "breslow")),
    "pql-ml": ("by penalised quasi-likelihood with maximum likelihood", ("breslow",)),
    "laplace": ("by maximum likelihood with the Laplace approximation", ()),
    "agq": ("by maximum likelihood with adaptive Gauss–Hermite quadrature", ()),
}


def _modelled(statistics: StatisticsDone) -> str:
    """``"elevation RMSE, SPARC and the iEMG of 8 muscles (entire cycle, raising, lowering)"``."""
    parts = list(statistics.kinematic_outcomes)
    order = ("entire", "raising", "lowering")
    phases = {phase: statistics.iemg_muscles[phase] for phase in sorted(
        statistics.iemg_muscles, key=lambda phase: order.index(phase) if phase in order else len(order),
    ) if statistics.iemg_muscles[phase]}
    if phases:
        muscles = max(phases.values())
        named = ", ".join("entire cycle" if phase == "entire" else phase for phase in phases)
        parts.append(f"the iEMG of {'each of ' if muscles > 1 else ''}{_count(muscles, 'muscle')} ({named})")
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]


def _fitted_by(method: str, cite: _Citations) -> str:
    """``"by pseudo-likelihood with REML, as SPSS GENLINMIXED [12][13]"``."""
    if method not in _GLMM_METHODS:
        return f"by {method}"
    text, keys = _GLMM_METHODS[method]
    return f"{text} {''.join(cite(key) for key in keys)}" if keys else text


def _glmm_sentences(statistics: StatisticsDone, cite: _Citations) -> list[str]:
    """The GLMMs as fitted: family, link, effects, fitting method, Type III tests, Holm comparisons."""
    fitted = dict.fromkeys(analysis.fit.method for analysis in statistics.analyses)
    how = " and ".join(_fitted_by(method, cite) for method in fitted)
    residual = all(np.isfinite(a.tests["df2"].astype(float)).all() for a in statistics.analyses)
    tests = "F tests with the residual degrees of freedom" if residual else "chi-square tests"
    sentences = [
        f"{_modelled(statistics)[0].upper()}{_modelled(statistics)[1:]} were each modelled by a generalised "
        "linear mixed model of the repetition-level values with a gamma distribution and log link, "
        "condition, speed and their interaction as fixed effects and a random intercept per participant, "
        f"fitted {how}.",
        f"The fixed effects were tested by Type III Wald {tests}; where an outcome's condition (speed) "
        "effect had p < 0.05, the conditions (speeds) were compared pairwise on their estimated marginal "
        f"means, pooled over the other factor, with Holm's correction {cite('holm')}.",
    ]
    if statistics.not_fitted:
        sentences.append(
            f"{_count(statistics.not_fitted, 'model')} could not be fitted (named in the notes)."
        )
    return sentences


def _friedman_sentence(statistics: StatisticsDone, cite: _Citations) -> str:
    """Friedman's test per questionnaire item; Bonferroni comparisons of mean ranks where p < 0.05."""
    items, compared = statistics.questionnaire_items, statistics.posthoc_items
    tested = (
        f"Questionnaire answers ({_count(items, 'item')}) were compared across conditions by Friedman's "
        f"test {cite('friedman')}"
    )
    if not compared:
        return f"{tested}; no item had p < 0.05, so none was compared pairwise."
    return (
        f"{tested}; for the {_count(compared, 'item')} with p < 0.05 the conditions' mean ranks were "
        f"compared pairwise with a Bonferroni correction, as MATLAB's multcompare {cite('hollander')}."
    )
