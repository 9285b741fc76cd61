"""Sweeps of controller and suit parameters over virtual cohorts, scored by tracking error, on Dask.

* :class:`SweepSpec` — axes (:mod:`bowden.sweep.axes`) × seeds, the cohort, protocol and
  identification; from TOML (:meth:`SweepSpec.from_toml`) or a preset (:func:`preset`).
* :func:`score_participant` / :func:`identify_suit` — the pure tasks a worker runs.
* :func:`dask_client` and :func:`run_sweep` — a local cluster or an existing scheduler; results in
  Parquet, resumable (:class:`SweepDirectory`).
* :func:`summarize_points`, :func:`cell_optima`, :func:`paired_difference` — the answer.

``docs/sweep.md`` explains the design and gives the shipped blend-velocity sweep's answer.
"""

from typing import TYPE_CHECKING

from bowden._lazy import lazy_exports

# Imported on first use (PEP 562): the command line's choices (the presets' names, the axes) should
# not pay for the runner's simulation, Dask and pandas (seconds of bowden --help).
_EXPORTS = {
    "AXES": "bowden.sweep.axes",
    "Axis": "bowden.sweep.axes",
    "PRESETS": "bowden.sweep.presets",
    "PairedDifference": "bowden.sweep.summary",
    "RESULT_COLUMNS": "bowden.sweep.task",
    "SweepDirectory": "bowden.sweep.output",
    "SweepPoint": "bowden.sweep.spec",
    "SweepRun": "bowden.sweep.runner",
    "SweepSpec": "bowden.sweep.spec",
    "cell_optima": "bowden.sweep.summary",
    "cohort": "bowden.sweep.runner",
    "dask_client": "bowden.engine.cluster",
    "identify_suit": "bowden.sweep.task",
    "paired_difference": "bowden.sweep.summary",
    "preset": "bowden.sweep.presets",
    "protocol_settings": "bowden.sweep.runner",
    "run_sweep": "bowden.sweep.runner",
    "score_participant": "bowden.sweep.task",
    "simulator_digest": "bowden.sim.digest",
    "summarize_points": "bowden.sweep.summary",
}

if TYPE_CHECKING:
    from bowden.engine.cluster import dask_client
    from bowden.sim.digest import simulator_digest
    from bowden.sweep.axes import AXES, Axis
    from bowden.sweep.output import SweepDirectory
    from bowden.sweep.presets import PRESETS, preset
    from bowden.sweep.runner import SweepRun, cohort, protocol_settings, run_sweep
    from bowden.sweep.spec import SweepPoint, SweepSpec
    from bowden.sweep.summary import PairedDifference, cell_optima, paired_difference, summarize_points
    from bowden.sweep.task import RESULT_COLUMNS, identify_suit, score_participant


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)


__all__ = [
    "AXES",
    "PRESETS",
    "RESULT_COLUMNS",
    "Axis",
    "PairedDifference",
    "SweepDirectory",
    "SweepPoint",
    "SweepRun",
    "SweepSpec",
    "cell_optima",
    "cohort",
    "dask_client",
    "identify_suit",
    "paired_difference",
    "preset",
    "protocol_settings",
    "run_sweep",
    "score_participant",
    "simulator_digest",
    "summarize_points",
]
