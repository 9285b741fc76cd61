"""What the browsers receive of a trial's rows: sample batches for the display and the console.

The loop's rows (``bowden.contracts.TRIAL_COLUMNS``) become one JSON-ready message per batch: the
display's (time, reference and measured elevation in degrees, and each row's wall stamp and
sequence number for the latency benchmark) and the console's, which adds the tensions — desired,
estimated from the measured motor torque, load cell —, the torques and the fault flags. Degrees
only here, at the edge (docs/design.md, "Contracts").
"""

from __future__ import annotations

from typing import Final

from bowden.contracts import TRIAL_COLUMNS
from bowden.control import Fault
from bowden.model import CompensationModel
from bowden.web.live import Stamped
from bowden.web.trial_setup import tension_estimate_n

_COLUMN: Final = {name: index for index, name in enumerate(TRIAL_COLUMNS)}
TIME: Final = _COLUMN["time_s"]
STATE: Final = _COLUMN["controller_state"]
FLAGS: Final = _COLUMN["fault_flags"]
_REF, _EL, _VEL = (_COLUMN[n] for n in ("reference_elevation_rad", "elevation_rad",
                                         "elevation_velocity_rad_s"))
_DES, _CMD, _TAU, _LOAD = (_COLUMN[n] for n in ("desired_tension_n", "commanded_torque_nm",
                                                 "motor_torque_nm", "tension_n"))
_DEG: Final = 57.29577951308232


def fault_names(flags: int) -> list[str]:
    """Names of the :class:`bowden.control.Fault` bits set in ``flags``."""
    return [f.name for f in Fault if f.value and flags & f.value and f.name is not None]


def display_samples(kept: list[Stamped]) -> dict[str, object]:
    """The display's message for a batch of stamped rows (no ids, elevation in degrees)."""
    rows = [s[2] for s in kept]
    return {
        "type": "samples",
        "seq": [s[1] for s in kept],
        "stamp_ms": [round(1e3 * s[0], 3) for s in kept],
        "t": [round(float(r[TIME]), 4) for r in rows],
        "reference_deg": [round(float(r[_REF]) * _DEG, 3) for r in rows],
        "elevation_deg": [round(float(r[_EL]) * _DEG, 3) for r in rows],
    }


def console_samples(
    display: dict[str, object], kept: list[Stamped], model: CompensationModel
) -> dict[str, object]:
    """The console's message: the display's plus tensions (N), torques (Nm) and fault flags."""
    rows = [s[2] for s in kept]
    console = dict(display)
    console.update(
        desired_tension_n=[round(float(r[_DES]), 3) for r in rows],
        estimated_tension_n=[
            round(tension_estimate_n(model, float(r[_TAU]), float(r[_VEL])), 3) for r in rows
        ],
        load_cell_tension_n=[round(float(r[_LOAD]), 3) for r in rows],
        commanded_torque_nm=[round(float(r[_CMD]), 4) for r in rows],
        motor_torque_nm=[round(float(r[_TAU]), 4) for r in rows],
        fault_flags=[int(r[FLAGS]) for r in rows],
    )
    return console
