"""Write the paper's published numbers into src/bowden/study/paper_values/*_data.py from its LaTeX.

Tables (by LaTeX label; the supplement numbers them S1-S12 in this order):

* Table 1 tab:torque_tension_tracking_RMSE_combined; S1 tab:tracking_pct_RMSE_combined; S2/S3
  tab:peak_torque_percentage_errors_raising/_lowering                                -> tracking_data.py
* S4 tab:shoulder_kinematics_statistical_results; S5 tab:shoulder_kinematics_condition_comparisons;
  S6 tab:shoulder_kinematics_velocity_comparisons                                    -> kinematics_data.py
* S7-S9 tab:iEMG_whole_mean/_raise_mean/_lower_mean; S10-S12 tab:pairwise_whole/_raising/_lowering;
  the colour tables tab:iEMG_deltas_visual (entire), _raising (Table 2), _lowering (Table 3)
                                                                                    -> iemg_data.py
* the questionnaire p-values of the Results text (subsection "Questionnaires")      -> questionnaire_data.py

Each generated module says it is generated; tests/study/test_paper_values.py re-runs this script's
rendering and fails when a module is not current. Run:

    python scripts/extract_paper_values.py path/to/sensorless-tension-control.tex
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from pathlib import Path

OUT = Path(__file__).resolve().parents[1] / "src" / "bowden" / "study" / "paper_values"
SPEEDS = ("V1", "V2", "V3")
PHASES = ("entire", "raising", "lowering")
CONDITION_NAMES = {"no": "no_suit", "pre": "pretension", "25%": "support_25", "50%": "support_50"}
MUSCLE_NAMES = {
    "ant. delt.": "anterior_deltoid",
    "med. delt.": "medial_deltoid",
    "post. delt.": "posterior_deltoid",
    "biceps": "biceps",
    "triceps": "triceps",
    "trapezius": "trapezius",
    "lat. dorsi": "latissimus_dorsi",
    "pectoralis": "pectoralis_major",
    "pectoralis maj.": "pectoralis_major",
    "pectoralis major": "pectoralis_major",
}
NUMBER = r"-?[0-9]+(?:\.[0-9]+)?"
CELL = re.compile(rf"({NUMBER})\s*\(({NUMBER})\)")


class ExtractionError(Exception):
    """The LaTeX does not hold a table or sentence in the form this script reads."""


# --- LaTeX to rows of cells ---------------------------------------------------------------------


def table_block(tex: str, label: str) -> str:
    """The table environment holding ``\\label{label}``."""
    for block in re.findall(r"\\begin\{table\}.*?\\end\{table\}", tex, re.S):
        if f"\\label{{{label}}}" in block:
            return str(block)
    raise ExtractionError(f"no table labelled {label}")


def _drop_command(text: str, command: str) -> str:
    """Remove every ``command{...}`` with its (possibly nested) braces."""
    while (start := text.find(command + "{")) >= 0:
        depth, index = 0, start + len(command)
        while True:
            depth += {"{": 1, "}": -1}.get(text[index], 0)
            index += 1
            if depth == 0:
                break
        text = text[:start] + text[index:]
    return text


def _clean(cell: str) -> str:
    cell = re.sub(r"\\multi(?:row|column)\{[^}]*\}\{[^}]*\}", "", cell)
    cell = re.sub(r"\\rule\{[^}]*\}\{[^}]*\}|\\[TB]strut|\\(?:hline|midrule|toprule|bottomrule)", "", cell)
    cell = cell.replace("\\%", "%").replace("$<$", "<").replace("$", "")
    cell = re.sub(r"\\textbf\{|\{|\}", "", cell)
    return " ".join(cell.split())


def rows(block: str) -> list[list[str]]:
    """The cells of each row of the block's (outer) tabular, LaTeX markup removed."""
    # Two-line cells are nested tabulars ("0.005\\ (0.021)"): one line.
    block = re.sub(
        r"\\begin\{tabular\}\[c\]\{@\{\}c@\{\}\}(.*?)\\end\{tabular\}",
        lambda m: m.group(1).replace("\\\\", " "),
        block,
        flags=re.S,
    )
    body = re.search(r"\\begin\{tabular\}\{[^\n]*?\}\s*\n(.*)\\end\{tabular\}", block, re.S)
    if body is None:
        raise ExtractionError("no tabular in the table")
    text = _drop_command(_drop_command(body.group(1), "\\makecell"), "\\multicolumn{1}{l}")
    return [[_clean(cell) for cell in row.split("&")] for row in text.split("\\\\")]


def p_literal(cell: str) -> str:
    """A printed p-value as a ``P(...)`` literal of the generated module."""
    if not re.fullmatch(rf"<?\s*{NUMBER}", cell):
        raise ExtractionError(f"not a p-value: {cell!r}")
    return f"P({' '.join(cell.replace('<', '< ').split())!r})"


def _number(cell: str) -> float:
    if not re.fullmatch(NUMBER, cell):
        raise ExtractionError(f"not a number: {cell!r}")
    return float(cell)


def _pair(label: str) -> tuple[str, str]:
    first, second = (part.strip() for part in label.split("-"))
    return CONDITION_NAMES.get(first, first), CONDITION_NAMES.get(second, second)


def _expect(what: str, found: int, expected: int) -> None:
    if found != expected:
        raise ExtractionError(f"{what}: read {found} values, expected {expected}")


# --- tracking: Table 1, S1-S3 ---------------------------------------------------------------------


def _condition_rows(block: str, width: int) -> list[tuple[str, list[str]]]:
    return [
        (CONDITION_NAMES[row[0].lower()], row[1:])
        for row in rows(block)
        if row and row[0].lower() in CONDITION_NAMES and len(row) == width + 1
    ]


def _phase_literal(name: str, found: list[tuple[str, list[str]]], comment: str) -> list[str]:
    out = [f"# {comment}", f"{name}: dict[tuple[str, str, str], float] = {{"]
    for condition, cells in found:
        for index, cell in enumerate(cells):
            speed, phase = SPEEDS[index // 3], PHASES[index % 3]
            out.append(f"    ({condition!r}, {speed!r}, {phase!r}): {_number(cell)!r},")
    return [*out, "}", ""]


def tracking(tex: str) -> list[str]:
    table1 = _condition_rows(table_block(tex, "tab:torque_tension_tracking_RMSE_combined"), 9)
    _expect("Table 1", len(table1), 6)
    pct = _condition_rows(table_block(tex, "tab:tracking_pct_RMSE_combined"), 9)
    _expect("Table S1", len(pct), 3)
    out = [
        *_phase_literal(
            "TORQUE_RMSE_NM", table1[:3], "Table 1 (torque rows): (condition, speed, phase) -> Nm"
        ),
        *_phase_literal(
            "TENSION_RMSE_N", table1[3:], "Table 1 (tension rows): (condition, speed, phase) -> N"
        ),
        *_phase_literal("PERCENT_ERROR_RMSE", pct, "Table S1: (condition, speed, phase) -> %"),
        "# Tables S2 (raising) and S3 (lowering): (phase, condition, speed) ->",
        "# (peak percent error, its SD, normalised time of the peak, its SD), all in %",
        "PEAK_PERCENT_ERROR: dict[tuple[str, str, str], tuple[float, float, float, float]] = {",
    ]
    for phase, label in (("raising", "raising"), ("lowering", "lowering")):
        found = _condition_rows(table_block(tex, f"tab:peak_torque_percentage_errors_{label}"), 6)
        _expect(f"peak errors {phase}", len(found), 3)
        for condition, cells in found:
            for index, speed in enumerate(SPEEDS):
                peak, time = (CELL.fullmatch(cell) for cell in cells[2 * index : 2 * index + 2])
                if peak is None or time is None:
                    raise ExtractionError(f"peak errors {phase} {condition} {speed}: {cells}")
                values = tuple(float(v) for v in (*peak.groups(), *time.groups()))
                out.append(f"    ({phase!r}, {condition!r}, {speed!r}): {values!r},")
    return [*out, "}"]


# --- kinematics: S4-S6 ----------------------------------------------------------------------------

KINEMATIC_OUTCOMES = {"RMSE": "elevation_rmse_deg", "SPARC": "sparc"}


def _kinematic_outcome(cell: str) -> str | None:
    return next((name for key, name in KINEMATIC_OUTCOMES.items() if cell.startswith(key)), None)


def kinematics(tex: str) -> list[str]:
    means = [
        "# Table S4: (outcome, speed, condition) -> (mean, SD); SPARC sign flipped to positive",
        "KINEMATICS: dict[tuple[str, str, str], tuple[float, float]] = {",
    ]
    pvalues = [
        "# Table S4: outcome -> p-values of condition, speed and their interaction (GLMM)",
        "KINEMATICS_P: dict[str, tuple[P, P, P]] = {",
    ]
    outcome = None
    for row in rows(table_block(tex, "tab:shoulder_kinematics_statistical_results")):
        if len(row) != 9 or row[1] not in SPEEDS:
            continue
        outcome = _kinematic_outcome(row[0]) or outcome
        for condition, cell in zip(CONDITION_NAMES.values(), row[2:6], strict=True):
            match = CELL.fullmatch(cell)
            if match is None or outcome is None:
                raise ExtractionError(f"Table S4: {row}")
            means.append(
                f"    ({outcome!r}, {row[1]!r}, {condition!r}): {tuple(map(float, match.groups()))!r},"
            )
        if all(row[6:9]):
            pvalues.append(f"    {outcome!r}: ({', '.join(p_literal(cell) for cell in row[6:9])}),")
    _expect("Table S4", len(means) - 2, 24)
    out = [*means, "}", "", *pvalues, "}", ""]
    for name, label, comment in (
        (
            "KINEMATICS_CONDITION_PAIRS",
            "tab:shoulder_kinematics_condition_comparisons",
            "Table S5 (SPARC only: no post-hoc test of RMSE, whose condition effect was not significant)\n#",
        ),
        ("KINEMATICS_SPEED_PAIRS", "tab:shoulder_kinematics_velocity_comparisons", "Table S6"),
    ):
        table = rows(table_block(tex, label))
        header = next(row for row in table if row and row[0] == "")
        pairs = [_pair(cell) for cell in header[1:] if cell]
        out += [
            f"# {comment}: (outcome, first, second) -> (change first - second, its SE, p)",
            f"{name}: dict[tuple[str, str, str], tuple[float, float, P]] = {{",
        ]
        for row in table:
            outcome = _kinematic_outcome(row[0]) if row else None
            if outcome is None or row[1] == "N/A":
                continue
            _expect(f"{label} {outcome}", len(row) - 1, 2 * len(pairs))
            for (first, second), change, p in zip(pairs, row[1::2], row[2::2], strict=True):
                match = CELL.fullmatch(change)
                if match is None:
                    raise ExtractionError(f"{label}: {change!r}")
                estimate, se = map(float, match.groups())
                out.append(
                    f"    ({outcome!r}, {first!r}, {second!r}): ({estimate!r}, {se!r}, {p_literal(p)}),"
                )
        out += ["}", ""]
    return out[:-1]


# --- iEMG: S7-S12 and the colour tables -----------------------------------------------------------

IEMG_MEANS = {
    "entire": "tab:iEMG_whole_mean",
    "raising": "tab:iEMG_raise_mean",
    "lowering": "tab:iEMG_lower_mean",
}
IEMG_PAIRS = {
    "entire": "tab:pairwise_whole",
    "raising": "tab:pairwise_raising",
    "lowering": "tab:pairwise_lowering",
}
IEMG_COLOURS = {
    "entire": "tab:iEMG_deltas_visual",
    "raising": "tab:iEMG_deltas_visual_raising",
    "lowering": "tab:iEMG_deltas_visual_lowering",
}
PAIRS = (
    ("pretension", "no_suit"),
    ("support_25", "no_suit"),
    ("support_50", "no_suit"),
    ("support_25", "pretension"),
    ("support_50", "pretension"),
    ("support_50", "support_25"),
)


def _muscle(cell: str) -> str:
    try:
        return MUSCLE_NAMES[cell.lower()]
    except KeyError:
        raise ExtractionError(f"unknown muscle {cell!r}") from None


def iemg(tex: str) -> list[str]:
    means = [
        "# Tables S7-S9: (phase, muscle, speed, condition) -> (mean, SD) of normalised iEMG",
        "IEMG: dict[tuple[str, str, str, str], tuple[float, float]] = {",
    ]
    pvalues = [
        "# Tables S7-S9: (phase, muscle) -> p-values of condition, speed and their interaction",
        "IEMG_P: dict[tuple[str, str], tuple[P, P, P]] = {",
    ]
    pairs = [
        "# Tables S10-S12: (phase, muscle, first, second) -> (change first - second, change in %, p)",
        "IEMG_PAIRS: dict[tuple[str, str, str, str], tuple[float, float, P]] = {",
    ]
    colours = [
        "# Table 2 (raising), Table 3 (lowering) and tab:iEMG_deltas_visual (entire):",
        "# (phase, muscle, first, second) -> (cell colour RGB, significance code as printed)",
        "IEMG_COLOURS: dict[tuple[str, str, str, str], tuple[tuple[int, int, int], str]] = {",
    ]
    for phase in PHASES:
        found, found_p = 0, 0
        speed_rows = [
            row for row in rows(table_block(tex, IEMG_MEANS[phase])) if len(row) == 9 and row[1] in SPEEDS
        ]
        # A muscle's name and p-values sit on one of its three speed rows (the middle one, multirow).
        for start in range(0, len(speed_rows), 3):
            group = speed_rows[start : start + 3]
            muscle = _muscle(next(row[0] for row in group if row[0]))
            for row in group:
                for condition, cell in zip(CONDITION_NAMES.values(), row[2:6], strict=True):
                    match = CELL.fullmatch(cell)
                    if match is None:
                        raise ExtractionError(f"{IEMG_MEANS[phase]}: {row}")
                    means.append(
                        f"    ({phase!r}, {muscle!r}, {row[1]!r}, {condition!r}): "
                        f"{tuple(map(float, match.groups()))!r},"
                    )
                    found += 1
                if all(row[6:9]):
                    pvalues.append(
                        f"    ({phase!r}, {muscle!r}): ({', '.join(p_literal(c) for c in row[6:9])}),"
                    )
                    found_p += 1
        _expect(IEMG_MEANS[phase], found + found_p, 96 + 8)
        found = 0
        for row in rows(table_block(tex, IEMG_PAIRS[phase])):
            if len(row) != 19 or row[0].lower() not in MUSCLE_NAMES:
                continue
            for (first, second), index in zip(PAIRS, range(1, 19, 3), strict=True):
                change, percent, p = row[index : index + 3]
                percent_value = _number(percent.strip("()%"))
                pairs.append(
                    f"    ({phase!r}, {_muscle(row[0])!r}, {first!r}, {second!r}): "
                    f"({_number(change)!r}, {percent_value!r}, {p_literal(p)}),"
                )
                found += 1
        _expect(IEMG_PAIRS[phase], found, 48)
        found = 0
        block = table_block(tex, IEMG_COLOURS[phase])
        body = block[block.index("\\hline", block.index("Muscle group")) :]
        for name, cells in re.findall(r"\n\s*([A-Z][A-Za-z. ]+?)\s*\n((?:\s*&[^\n]*\n?){6})", body):
            for (first, second), cell in zip(PAIRS, re.findall(r"&([^\n&]*)", cells), strict=True):
                rgb = re.search(r"\\cellcolor\[RGB\]\{(\d+),(\d+),(\d+)\}", cell)
                if rgb is None:
                    raise ExtractionError(f"{IEMG_COLOURS[phase]}: {cell!r}")
                code = "".join(re.findall(r"\*", cell))
                colours.append(
                    f"    ({phase!r}, {_muscle(name)!r}, {first!r}, {second!r}): "
                    f"({tuple(map(int, rgb.groups()))!r}, {code!r}),"
                )
                found += 1
        _expect(IEMG_COLOURS[phase], found, 48)
    return [*means, "}", "", *pvalues, "}", "", *pairs, "}", "", *colours, "}"]


# --- questionnaires: the Results text -------------------------------------------------------------

FATIGUE_NAMES = {
    "deltoids": "deltoids",
    "pectoralis major": "pectoralis_major",
    "trapezius": "trapezius",
    "biceps": "biceps",
    "latissimus dorsi": "latissimus_dorsi",
    "triceps": "triceps",
}
NORDIC_NAMES = {"lower neck": "lower_neck", "right shoulder": "right_shoulder", "shoulder": "right_shoulder"}
TEXT_P = r"\(?\$p\s*([<=])\s*([0-9.]+)\$\)?"


def _text_p(sign: str, value: str) -> str:
    return p_literal(("< " if sign == "<" else "") + value)


def questionnaires(tex: str) -> list[str]:
    start = tex.index("\\subsubsection{Questionnaires}", tex.index("\\section{Results}"))
    text = " ".join(tex[start : tex.index("\\begin{figure}", start)].split())
    out = [
        "# Friedman tests across conditions (Results, Questionnaires): (questionnaire, item) -> p",
        "QUESTIONNAIRE_P: dict[tuple[str, str], P] = {",
    ]
    for site, sign, value in re.findall(rf"(lower neck|right shoulder) {TEXT_P}", text):
        out.append(f"    ('nordic', {NORDIC_NAMES[site]!r}): {_text_p(sign, value)},")
    rpe = re.search(rf"RPE did not change significantly {TEXT_P}", text)
    if rpe is None:
        raise ExtractionError("no RPE p-value in the Questionnaires results")
    out.append(f"    ('borg_rpe', 'rpe'): {_text_p(*rpe.groups())},")
    for name, sign, value in re.findall(
        rf"(deltoids|pectoralis major|trapezius|biceps|latissimus dorsi|"
        rf"triceps) {TEXT_P}",
        text,
    ):
        out.append(f"    ('fatigue', {FATIGUE_NAMES[name]!r}): {_text_p(sign, value)},")
    _expect("questionnaire p-values", len(out) - 2, 2 + 1 + 6)
    out += [
        "}",
        "",
        "# Post-hoc comparisons the text reports (Bonferroni): (item, from, to) -> (direction, p);",
        "# the text gives only the significant ones, each an increase from the first to the second",
        "NORDIC_PAIRS: dict[tuple[str, str, str], tuple[str, P]] = {",
    ]
    found = 0
    for sentence in re.findall(
        r"discomfort in the (lower neck|shoulder) area significantly (increased)(.*?)\.(?: |$)", text
    ):
        site, direction, rest = sentence
        for origin, targets in re.findall(
            r"from the (no-suit|pretension) condition to the (.*?)(?=and also from|$)", rest
        ):
            first = "no_suit" if origin == "no-suit" else "pretension"
            for target, sign, value in re.findall(
                rf"(pretension|25%|50%)[^(]*?{TEXT_P}", targets.replace("\\%", "%")
            ):
                second = CONDITION_NAMES.get("pre" if target == "pretension" else target)
                out.append(
                    f"    ({NORDIC_NAMES[site]!r}, {first!r}, {second!r}): "
                    f"({'increase' if direction == 'increased' else direction!r}, {_text_p(sign, value)}),"
                )
                found += 1
    _expect("Nordic post-hoc p-values", found, 6)
    return [*out, "}"]


# --- output ---------------------------------------------------------------------------------------

MODULES: dict[str, tuple[Callable[[str], list[str]], str]] = {
    "tracking_data.py": (tracking, "Table 1 and Supplementary Tables S1-S3 (tension/torque tracking)"),
    "kinematics_data.py": (kinematics, "Supplementary Tables S4-S6 (elevation RMSE and SPARC)"),
    "iemg_data.py": (
        iemg,
        "Supplementary Tables S7-S12 and the iEMG colour Tables 2, 3 and tab:iEMG_deltas_visual",
    ),
    "questionnaire_data.py": (questionnaires, "the questionnaire results of the paper's Results text"),
}


def render(tex: str) -> dict[str, str]:
    """The text of every generated module, by file name."""
    out = {}
    for name, (extract, what) in MODULES.items():
        lines = extract(tex)
        out[name] = "\n".join(
            [
                '"""The paper\'s published values:',
                f"{what}.",
                "",
                "Generated by scripts/extract_paper_values.py from the paper's LaTeX source;",
                "do not edit by hand.",
                'A p-value printed "< 0.001" is P("< 0.001"): an upper bound (P.upper_bound is True).',
                '"""',
                "",
                "# fmt: off",
                "from __future__ import annotations",
                "",
                *(["from bowden.study.paper_values.pvalue import P", ""] if "P(" in "".join(lines) else []),
                *lines,
                "",
            ]
        )
    return out


def main() -> None:
    if len(sys.argv) != 2:
        raise SystemExit(
            "usage: python scripts/extract_paper_values.py path/to/sensorless-tension-control.tex"
        )
    tex = Path(sys.argv[1]).read_text(encoding="utf-8")
    for name, text in render(tex).items():
        (OUT / name).write_text(text, encoding="utf-8")
        print(f"wrote {OUT / name}")


if __name__ == "__main__":
    main()
