"""The identified dynamic friction against cable velocity (``bowden identify --friction-figure``).

Each steady-state sample's friction torque — motor torque minus the frictionless mean of the two
lines at its tension — against the cable velocity at the spool (R·ω), with the dynamic model's law
for the lowest, median and highest tension of the recording: the jump at zero is the load-proportional
Coulomb friction, the slope on either side the drag that the paper's per-direction lines cannot show.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from bowden.errors import OutputFileError
from bowden.identify.figure import COLOURS, MAX_POINTS_PER_DIRECTION, _thin
from bowden.identify.preprocess import SteadyStateSelection
from bowden.identify.settings import LOWERING, RAISING
from bowden.model.dynamic import DynamicCompensation


def plot_friction(
    selection: SteadyStateSelection, dynamic: DynamicCompensation, pulley_radius_m: float
) -> Figure:
    """Draw the samples' friction torque and the model's friction law against cable velocity."""
    figure = Figure(figsize=(6.4, 4.8), dpi=120, layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    f = selection.filtered
    all_tension = f.tension_n[selection.selected]
    for direction in (RAISING, LOWERING):
        mask = selection.direction_mask(direction)
        tension = f.tension_n[mask]
        mean = 0.5 * (dynamic.raising.torque_nm(tension) + dynamic.lowering.torque_nm(tension))  # type: ignore[arg-type]
        keep = _thin(tension.size, MAX_POINTS_PER_DIRECTION)
        axes.scatter(
            pulley_radius_m * f.motor_velocity_rad_s[mask][keep],
            (f.motor_torque_nm[mask] - mean)[keep],
            s=4,
            alpha=0.25,
            color=COLOURS[direction],
            linewidths=0,
            rasterized=True,
            label=f"{direction} samples",
        )
    top = float(np.max(np.abs(pulley_radius_m * f.motor_velocity_rad_s[selection.selected])))
    velocity = np.linspace(-top, top, 401)
    velocity = velocity[velocity != 0.0]
    for tension, style in zip(np.percentile(all_tension, [0, 50, 100]), (":", "-", "--"), strict=True):
        law = [dynamic.friction_nm(float(tension), float(v / pulley_radius_m)) for v in velocity]
        for side in (velocity < 0.0, velocity > 0.0):
            axes.plot(
                velocity[side],
                np.asarray(law)[side],
                color="black",
                linestyle=style,
                linewidth=1.5,
                label=f"model at T = {tension:.0f} N" if side[-1] else None,
            )
    axes.axvline(0.0, color="grey", linewidth=0.8)
    axes.set_xlabel("cable velocity at the spool, $R\\,\\omega$ [m/s] (> 0: into the sheath, raising)")
    axes.set_ylabel("friction torque at the motor [Nm]")
    axes.set_title(
        f"Dynamic friction: drag {dynamic.viscous_nm_s_rad * 1e3:.1f} mNm·s/rad, "
        f"inertia {dynamic.inertia_kg_m2 * 1e3:.2f} g·m²"
    )
    axes.grid(True, alpha=0.3)
    axes.legend(loc="upper left", fontsize="small")
    return figure


def save_friction_figure(
    selection: SteadyStateSelection, dynamic: DynamicCompensation, pulley_radius_m: float, path: str | Path
) -> Path:
    """Draw :func:`plot_friction` and write it to ``path`` (format from the suffix)."""
    target = Path(path)
    figure = plot_friction(selection, dynamic, pulley_radius_m)
    try:
        figure.savefig(target)
    except (OSError, ValueError) as error:
        raise OutputFileError(f"cannot write the figure to {target}: {error}") from None
    return target
