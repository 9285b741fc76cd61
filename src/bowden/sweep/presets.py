"""Named sweeps shipped with bowden (``bowden sweep PRESET``).

``blend-velocity`` answers the question the paper leaves open (Discussion: "a more thorough
exploration of the sigmoid coupling parameters ... may also reduce the effect of this disturbance"):
which blend velocities θ̇₀₀₁ and θ̇₀₉₉ minimise the tension RMSE and the spike of tension error at
the onset of lowering. The grid spans the paper's −1/+1 rad/s, blends twice as wide, and narrow
blends down to 0.1 rad/s shifted to either side of zero; the full cohort of 17 runs every support
condition at every speed with the paper's ten repetitions, on the lines identified on the paper's
bench protocol.
"""

from __future__ import annotations

from bowden.errors import ParameterError
from bowden.sweep import axes as ax
from bowden.sweep.spec import SweepSpec

BLEND_VELOCITY = "blend-velocity"

PRESETS: dict[str, SweepSpec] = {
    BLEND_VELOCITY: SweepSpec(
        name=BLEND_VELOCITY,
        axes=(
            (ax.BLEND_01, (-2.0, -1.0, -0.5, -0.25, -0.1, 0.0, 0.1)),
            (ax.BLEND_99, (0.0, 0.1, 0.25, 0.5, 1.0, 2.0)),
        ),
        participants=17,
        seeds=(0,),
        repetitions=10,
        identification="per-suit",
        bench="paper",
    ),
}


def preset(name: str) -> SweepSpec:
    """The preset called ``name``; a :class:`ParameterError` listing the presets otherwise."""
    spec = PRESETS.get(name)
    if spec is None:
        raise ParameterError(f"unknown sweep preset {name!r}; presets: {', '.join(PRESETS)}")
    return spec
