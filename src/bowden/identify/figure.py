"""The identification figure, like the paper's regression plot ("Model identification on mannequin").

Load-cell tension on x (the controller's desired tension), motor torque on y, raising samples and
line in blue, lowering in orange, each line annotated with its slope, intercept and R². The figure is
drawn on matplotlib's Agg canvas directly (no pyplot, no global state, no display needed).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bowden.errors import OutputFileError
from bowden.identify.preprocess import SteadyStateSelection
from bowden.identify.robustfit import RobustFit
from bowden.identify.settings import LOWERING, RAISING

# The paper's colours: raising blue, lowering orange (matplotlib's default C0 and C1).
COLOURS = {RAISING: "#1f77b4", LOWERING: "#ff7f0e"}
MAX_POINTS_PER_DIRECTION = 4000  # a scatter of a million points says no more and takes seconds


def _thin(count: int, limit: int) -> np.ndarray:
    """Evenly spaced indices, at most ``limit`` of them (deterministic, keeps the time order)."""
    if count <= limit:
        return np.arange(count)
    return np.linspace(0, count - 1, limit).round().astype(np.intp)


def plot_identification(
    selection: SteadyStateSelection,
    fits: dict[str, RobustFit],
    *,
    title: str = "Transmission identification",
    max_points_per_direction: int = MAX_POINTS_PER_DIRECTION,
) -> Figure:
    """Draw the selected samples and both robust lines.

    Parameters
    ----------
    selection
        The steady-state selection the lines were fitted to.
    fits
        ``{"raising": RobustFit, "lowering": RobustFit}``.
    title
        Axes title.
    max_points_per_direction
        Scatter at most this many (evenly thinned) samples per direction; the lines use all.
    """
    figure = Figure(figsize=(6.4, 4.8), dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    top = 0.0
    bottom = 0.0
    for direction in (RAISING, LOWERING):
        tension = selection.tension_n(direction)
        torque = selection.motor_torque_nm(direction)
        fit = fits[direction]
        keep = _thin(tension.size, max_points_per_direction)
        axes.scatter(
            tension[keep],
            torque[keep],
            s=4,
            alpha=0.25,
            color=COLOURS[direction],
            linewidths=0,
            rasterized=True,
        )
        span = np.array([0.0, float(tension.max())])
        label = (
            f"{direction}: τ = {fit.intercept:+.3f} Nm + {1e3 * fit.slope:.2f} mm · T   "
            f"R² = {fit.r_squared_fitlm_robust:.4f} (n = {fit.n})"
        )
        axes.plot(span, fit.intercept + fit.slope * span, color=COLOURS[direction], linewidth=2, label=label)
        top = max(top, float(span[1]))
        bottom = min(bottom, fit.intercept)
    axes.set_xlim(0.0, 1.05 * top)
    axes.set_ylim(bottom=bottom - 0.02 * abs(bottom))
    axes.set_xlabel("cable tension at the arm, $T_{out}$ [N]")
    axes.set_ylabel("motor torque, $\\tau$ [Nm]")
    axes.set_title(title)
    axes.grid(True, alpha=0.3)
    axes.legend(loc="upper left", fontsize="small", title="robust fits (R²: fitlm robust definition)")
    return figure


def save_identification_figure(
    selection: SteadyStateSelection, fits: dict[str, RobustFit], path: str | Path, **kwargs: object
) -> Path:
    """Draw :func:`plot_identification` and write it to ``path`` (format from the suffix)."""
    target = Path(path)
    figure = plot_identification(selection, fits, **kwargs)  # type: ignore[arg-type]
    try:
        figure.savefig(target)
    except (OSError, ValueError) as error:
        raise OutputFileError(f"cannot write the figure to {target}: {error}") from None
    return target
