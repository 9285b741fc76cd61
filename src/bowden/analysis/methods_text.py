"""The methods paragraph of the analysis, written from the parameters actually used.

Like NeuroKit's ``emg_methods``: the report states exactly what was done, so that changing a
parameter changes the text and no description can drift from the code.
"""

from __future__ import annotations

from dataclasses import dataclass

from bowden.analysis.outcomes import AnalysisInfo, AnalysisParameters

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


def methods_text(
    parameters: AnalysisParameters | None = None, info: AnalysisInfo | None = None
) -> MethodsText:
    """Describe the analysis done with ``parameters`` (and, if given, the counts of ``info``)."""
    p = parameters or (info.parameters if info is not None else AnalysisParameters())
    emg = p.emg
    cited: list[str] = []

    def cite(key: str) -> str:
        if key not in cited:
            cited.append(key)
        return f"[{cited.index(key) + 1}]"

    sentences = []
    if info is not None:
        sentences.append(
            f"Data of {info.n_participants} participants ({info.n_trials} trials, {info.n_repetitions} "
            "repetitions after exclusions) were analysed."
        )
    sentences.append(
        f"EMG signals were band-pass filtered with a zero-phase (forward-backward) Butterworth filter "
        f"{cite('butterworth')} of order {emg.filter_order} between {emg.low_hz:g} and {emg.high_hz:g} Hz "
        f"(−6 dB at both cut-offs after the two passes), full-wave rectified, and smoothed with a sliding "
        f"root-mean-square window of {1000.0 * emg.envelope_window_s:g} ms {cite('burden')}."
    )
    if emg.ecg_removal != "none" and emg.ecg_channels:
        muscles = " and ".join(name.replace("_", " ") for name in emg.ecg_channels)
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
        if emg.ecg_removal == "adaptive":
            e = emg.ecg
            sentences.append(
                f"The cardiac artefact was removed from the {muscles} by adaptive template subtraction "
                f"{cite('petersen')}: beats were cut at the midpoints between R-peaks, each beat's template "
                "was "
                f"the mean of the {e.template_beats} surrounding beats, aligned by cross-correlation "
                f"(±{e.max_shift_samples} samples), its QRS part (R ± {1000.0 * e.qrs_half_width_s:g} ms) "
                "was "
                f"stretched by −{e.stretch_samples}…+{e.stretch_samples} samples per side using PCHIP "
                f"interpolation {cite('fritsch')}, P, QRS and T sections were scaled and offset by least "
                f"squares, and the best-fitting variant was subtracted."
            )
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
        else:
            sentences.append(
                f"The cardiac artefact was removed from the {muscles} by template subtraction "
                f"{cite('petersen')}, subtracting at each R-peak the mean of the "
                f"{emg.ecg.template_beats} surrounding beats."
            )
    seg = p.segmentation
    source = {
        "reference": "the reference trajectory",
        "elevation": "the measured elevation",
        "auto": "the reference trajectory (the measured elevation where no reference was recorded)",
    }
    drop = (
        f" The first {'repetition' if seg.drop_first == 1 else f'{seg.drop_first} repetitions'} of each "
        f"trial {'was' if seg.drop_first == 1 else 'were'} excluded to avoid adaptation effects "
        f"{cite('emken')}."
        if seg.drop_first
        else ""
    )
    sentences.append(
        f"Repetitions were segmented on {source[seg.source]} and split at the highest elevation into raising "
        f"and lowering phases.{drop} Each repetition was resampled onto a normalised time vector of "
        f"{seg.n_points} points."
    )
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
    return MethodsText(paragraph=" ".join(sentences), references=tuple(REFERENCES[k] for k in cited))
