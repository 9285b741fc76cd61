"""The tables of docs/sweep.md, "The answer: blend velocities", from a blend-velocity sweep's output.

Run: python benchmarks/sweep_answer.py OUT   (OUT is the ``--out`` directory of
``bowden sweep blend-velocity``; it must hold ``results.parquet`` and ``points.parquet``)

Prints markdown: the mean tension RMSE and mean |lowering peak| over the blend grid, the signed
lowering and raising peaks, the Pareto front with its raising/lowering split, paired differences from
the paper's blend over participants (95 % t-intervals), the best blend of each condition and speed
with the paper's blend beside it, the 3×3 tables of the best blends and of the paper's blend, and the
data-dependent numbers of the physical explanation. Every number is computed here from the rows, with
the summary functions of :mod:`bowden.sweep.summary`, so the document can be regenerated after a new
run.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from bowden.sweep import axes as ax
from bowden.sweep import summary as sm
from bowden.sweep.task import PEAK_PERCENT_ERROR_ABS

CONDITIONS = (("pretension", "pre"), ("support_25", "25 %"), ("support_50", "50 %"))
SPEEDS = ("V1", "V2", "V3")
# Simulated IMU velocity noise, 1 σ (docs/simulation.md): 1.5 °/s.
VELOCITY_NOISE_RAD_S = math.radians(1.5)


def fmt_velocity(value: float) -> str:
    """A blend velocity as the document writes it: −0.1, 0.25, 1 (true minus sign)."""
    text = f"{value:g}"
    return text.replace("-", "−")


def blend_name(b01: float, b99: float) -> str:
    return f"({fmt_velocity(b01)}, {fmt_velocity(b99)})"


def signed(value: float, digits: int = 1) -> str:
    text = f"{value:+.{digits}f}"
    return text.replace("-", "−")


def grid_table(points: pd.DataFrame, measure: str, digits: int, title: str) -> str:
    """Rows θ̇₀₀₁, columns θ̇₀₉₉; the best cell and the paper's cell in bold."""
    grid = points.pivot(index=ax.BLEND_01, columns=ax.BLEND_99, values=measure)
    best = points.loc[points[measure].idxmin()]
    header = " | ".join(fmt_velocity(c) for c in grid.columns)
    lines = [f"### {title}", "", f"| θ̇₀₀₁ \\ θ̇₀₉₉ | {header} |"]
    lines.append("|---" * (len(grid.columns) + 1) + "|")
    for b01, row in grid.iterrows():
        cells = []
        for b99, value in row.items():
            if np.isnan(value):
                cells.append("–")
                continue
            text = f"{value:.{digits}f}"
            is_paper = math.isclose(float(b01), ax.PAPER_BLEND_01_RAD_S) and math.isclose(
                float(b99), ax.PAPER_BLEND_99_RAD_S
            )
            is_best = math.isclose(float(b01), best[ax.BLEND_01]) and math.isclose(
                float(b99), best[ax.BLEND_99]
            )
            if is_best:
                text = f"**{text}** (best)"
            if is_paper:
                text = f"**{text}** (paper)"
            cells.append(text)
        lines.append(f"| {fmt_velocity(float(b01))} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def phase_peaks(results: pd.DataFrame) -> pd.DataFrame:
    """Per configuration: mean signed and |peak| % error and its time, raising and lowering."""
    out = {}
    for phase in ("raising", "lowering"):
        rows = results[results["phase"] == phase].groupby("config_id")
        out[f"{phase}_signed"] = rows["peak_percent_error_pct"].mean()
        out[f"{phase}_abs"] = rows[PEAK_PERCENT_ERROR_ABS].mean()
        out[f"{phase}_time"] = rows["peak_percent_error_time_pct"].mean()
    return pd.DataFrame(out)


def cell_means(results: pd.DataFrame, config_id: str, measure: str, phase: str) -> pd.DataFrame:
    rows = results[(results["config_id"] == config_id) & (results["phase"] == phase)]
    return rows.groupby(["condition", "speed"])[measure].mean().unstack("speed")


def three_by_three(results: pd.DataFrame, config_id: str, title: str) -> str:
    table = cell_means(results, config_id, "tension_rmse_n", "entire")
    lines = [f"| {title} | V1 | V2 | V3 |", "|---|---|---|---|"]
    for condition, label in CONDITIONS:
        lines.append(f"| {label} | " + " | ".join(f"{table.loc[condition, s]:.2f}" for s in SPEEDS) + " |")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="the sweep's --out directory")
    args = parser.parse_args()
    results_path, points_path = args.out / "results.parquet", args.out / "points.parquet"
    for path in (results_path, points_path):
        if not path.is_file():
            print(f"error: {path} not found (run bowden sweep blend-velocity --out {args.out})")
            return 1
    results = pd.read_parquet(results_path)
    points = pd.read_parquet(points_path).set_index("config_id")
    points = points.join(phase_peaks(results))
    paper_rows = points[points[sm.PAPER_BLEND]]
    if paper_rows.empty:
        print("error: the sweep does not hold the paper's blend (−1, +1 rad/s)")
        return 1
    paper_id = str(paper_rows.index[0])
    paper = paper_rows.iloc[0]
    best_rmse_id = str(points[sm.TENSION].idxmin())
    best_spike_id = str(points[sm.SPIKE].idxmin())

    def name(config_id: str) -> str:
        row = points.loc[config_id]
        return blend_name(row[ax.BLEND_01], row[ax.BLEND_99])

    n_participants = int(points[sm.TENSION].size and points["n_participants"].max())
    print(f"<!-- {len(points)} blends, {n_participants} participants, {len(results)} rows -->\n")
    print(grid_table(points.reset_index(), sm.TENSION, 2, "Mean tension RMSE over the entire cycle (N)"))
    print()
    print(grid_table(points.reset_index(), sm.SPIKE, 1,
                     "Mean |peak percent error| while lowering (%): the lowering-onset spike"))
    print()

    front = points[points[sm.PARETO]].sort_values(sm.TENSION)
    print("### Signed peaks (mean over rows, %; time in % of the cycle)\n")
    print("| blend | lowering signed | lowering \\|peak\\| | at (%) | raising signed | raising at (%) |")
    print("|---|---|---|---|---|---|")
    for config_id in [*front.index, paper_id]:
        row = points.loc[config_id]
        print(f"| {name(config_id)} | {signed(row['lowering_signed'])} | {row['lowering_abs']:.1f} | "
              f"{row['lowering_time']:.1f} | {signed(row['raising_signed'])} | {row['raising_time']:.1f} |")
    # How often the paper blend's lowering peak is positive, per trial cell (each row: mean of 9 reps).
    lowering = results[(results["config_id"] == paper_id) & (results["phase"] == "lowering")]
    positive = float((lowering["peak_percent_error_pct"] > 0).mean())
    print(f"\npaper blend: lowering peak positive in {100 * positive:.0f} % of participant×cell rows\n")

    print("### The Pareto front\n")
    print("| θ̇₀₀₁, θ̇₀₉₉ (rad/s) | tension RMSE (N) | raising | lowering | \\|lowering peak\\| (%) "
          "| signed | at (%) |")
    print("|---|---|---|---|---|---|---|")
    for config_id in [*front.index, paper_id]:
        row = points.loc[config_id]
        label = name(config_id)[1:-1]
        if config_id == best_rmse_id:
            label = f"**{label}** (lowest RMSE)"
        if config_id == best_spike_id:
            label = f"**{label}** (smallest spike)"
        if config_id == paper_id:
            label = f"paper: {label}"
        print(f"| {label} | {row[sm.TENSION]:.2f} | {row[sm.TENSION_RAISING]:.2f} | "
              f"{row[sm.TENSION_LOWERING]:.2f} | {row[sm.SPIKE]:.1f} | {signed(row[sm.SPIKE_SIGNED])} | "
              f"{row[sm.SPIKE_TIME]:.1f} |")
    centres = 0.5 * (front[ax.BLEND_01] + front[ax.BLEND_99])
    print(f"\nfront: θ̇₀₀₁ in [{front[ax.BLEND_01].min():g}, {front[ax.BLEND_01].max():g}], "
          f"θ̇₀₉₉ in [{front[ax.BLEND_99].min():g}, {front[ax.BLEND_99].max():g}], "
          f"centre M in [{centres.min():g}, {centres.max():g}] rad/s\n")

    print(f"### Paired differences from the paper's blend, over the {n_participants} participants "
          "(mean [95 % t-interval])\n")
    print("| | tension RMSE, entire (N) | tension RMSE, lowering (N) | \\|lowering peak\\| (%) "
          "| elevation RMSE (deg) |")
    print("|---|---|---|---|---|")
    measures = (
        ("tension_rmse_n", "entire", 1.0, 2),
        ("tension_rmse_n", "lowering", 1.0, 2),
        (PEAK_PERCENT_ERROR_ABS, "lowering", 1.0, 1),
        ("elevation_rmse_rad", "entire", math.degrees(1.0), 2),
    )
    for config_id in front.index:
        cells = []
        for measure, phase, scale, digits in measures:
            d = sm.paired_difference(results, config_id, paper_id, measure=measure, phase=phase)
            cells.append(f"{signed(scale * d.mean, digits)} [{signed(scale * d.low, digits)}, "
                         f"{signed(scale * d.high, digits)}]")
        print(f"| {name(config_id)} | " + " | ".join(cells) + " |")
    print()

    print("### Per support condition and speed\n")
    rmse = sm.cell_optima(results, measure="tension_rmse_n", phase="entire")
    spike = sm.cell_optima(results, measure=PEAK_PERCENT_ERROR_ABS, phase="lowering")
    print("| | tension RMSE: best blend → N (paper) | \\|lowering peak\\|: best blend → % (paper) |")
    print("|---|---|---|")
    for condition, label in CONDITIONS:
        for speed in SPEEDS:
            r = rmse[(rmse["condition"] == condition) & (rmse["speed"] == speed)].iloc[0]
            s = spike[(spike["condition"] == condition) & (spike["speed"] == speed)].iloc[0]
            print(f"| {label} {speed} | {blend_name(r[ax.BLEND_01], r[ax.BLEND_99])} → {r['best']:.2f} "
                  f"({r['paper_blend']:.2f}) | {blend_name(s[ax.BLEND_01], s[ax.BLEND_99])} → "
                  f"{s['best']:.1f} ({s['paper_blend']:.1f}) |")
    print()

    for config_id in dict.fromkeys([best_rmse_id, best_spike_id, paper_id]):
        print(f"{name(config_id)}, tension RMSE (N):\n")
        print(three_by_three(results, config_id, "tension RMSE (N)"))
        print()
    best_cells = cell_means(results, best_rmse_id, "tension_rmse_n", "entire")
    paper_cells = cell_means(results, paper_id, "tension_rmse_n", "entire")
    paper_spikes = cell_means(results, paper_id, PEAK_PERCENT_ERROR_ABS, "lowering")
    grows = all(
        best_cells.loc[c, "V1"] < best_cells.loc[c, "V2"] < best_cells.loc[c, "V3"] for c, _ in CONDITIONS
    )
    print(f"best-RMSE blend: RMSE grows V1<V2<V3 in every condition: {grows}")
    lower = bool((best_cells < paper_cells).all().all())
    print(f"best-RMSE blend: lower RMSE than the paper blend in every cell: {lower}")
    gain = paper_cells - best_cells
    print("its RMSE gain over the paper blend by speed (N): "
          + ", ".join(f"{s} {gain[s].min():.2f}–{gain[s].max():.2f}" for s in SPEEDS))
    for config_id in front.index:
        spikes = cell_means(results, config_id, PEAK_PERCENT_ERROR_ABS, "lowering")
        worse = [
            f"{condition} {speed} ({spikes.loc[condition, speed]:.1f} "
            f"vs {paper_spikes.loc[condition, speed]:.1f})"
            for condition, _ in CONDITIONS
            for speed in SPEEDS
            if spikes.loc[condition, speed] >= paper_spikes.loc[condition, speed]
        ]
        listed = ", ".join(worse) or "none"
        print(f"{name(config_id)}: |lowering peak| not below the paper blend's in: {listed}")
    print()

    print("### Physics numbers\n")
    first = results.iloc[0]
    raising_m, lowering_m = float(first["model_raising_slope_m"]), float(first["model_lowering_slope_m"])
    print(f"identified slopes: raising {1e3 * raising_m:.1f} mm, lowering {1e3 * lowering_m:.1f} mm, "
          f"ratio {raising_m / lowering_m:.2f}")
    half = lowering_m + 0.5 * (raising_m - lowering_m)
    print(f"w = 1/2: {100 * half / raising_m:.0f} % of the need while raising, "
          f"{100 * half / lowering_m:.0f} % while lowering")
    rel = (points[sm.TENSION] - paper[sm.TENSION]) / paper[sm.TENSION]
    print(f"best RMSE {points.loc[best_rmse_id, sm.TENSION]:.2f} N vs paper {paper[sm.TENSION]:.2f} N "
          f"({100 * rel[best_rmse_id]:+.0f} %)")
    print(f"lowering peak times over the front and the paper blend: "
          f"{points.loc[[*front.index, paper_id], sm.SPIKE_TIME].min():.1f}–"
          f"{points.loc[[*front.index, paper_id], sm.SPIKE_TIME].max():.1f} % of the cycle")
    for config_id in dict.fromkeys([*front.index, paper_id]):
        width = points.loc[config_id, ax.BLEND_99] - points.loc[config_id, ax.BLEND_01]
        dw = VELOCITY_NOISE_RAD_S * math.log(99.0) / (2.0 * width)
        print(f"  {name(config_id)}: 1 σ of velocity noise moves w by ≈ {dw:.2f}")
    narrow = points[(points[ax.BLEND_99] - points[ax.BLEND_01]) <= 0.1 + 1e-9]
    for config_id in narrow.index:
        dw = VELOCITY_NOISE_RAD_S * math.log(99.0) / (2.0 * 0.1)
        print(f"  {name(config_id)} (width 0.1): ≈ {dw:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
