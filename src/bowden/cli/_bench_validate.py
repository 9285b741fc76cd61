"""``bowden bench validate MODEL --backend can|sim-wire``: the study-like segment on a bench in real time.

Private to the CLI. The bench runs only the protocol's study-like strokes (docs/identification.md,
"The protocol, exactly", segment 3) with MODEL's compensations in turn — the slack taken up first, no
identification strokes, no chirp — recorded crash-safe like ``bench run`` (``--resume``).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from bowden.cli._bench_run import bench_config, run_bench_config, study_strokes
from bowden.errors import ParameterError
from bowden.model import CompensationModel


def run_study_on_bench(args: argparse.Namespace, model: CompensationModel,
                       supports: tuple[float | str, ...]) -> Path | None:
    """Run the study-like blocks of ``model`` on the bench of ``args``; the study recording's path,
    or None when the bench stopped (said on stderr)."""
    model_path = Path(args.model)
    output = Path(args.bench_output or model_path.with_name(model_path.stem + ".validate.csv"))
    run_args = argparse.Namespace(**vars(args))
    run_args.backend = "sim" if args.backend == "sim-wire" else "can"
    run_args.output = output
    run_args.speeds = run_args.loads = run_args.repetitions = None
    run_args.study_supports = [str(support) for support in supports]
    run_args.no_later_segments = True
    config = bench_config(run_args)
    study = study_strokes(run_args)
    if model.dynamic is None:
        study = replace(study, compensations=("paper",))
    config = replace(config, identification=False, latency=None, study=study)
    if run_args.backend == "can" and args.i2c_bus is None:
        raise ParameterError("bowden bench validate --backend can needs the load cell (--i2c-bus N): it "
                             "judges the compensations against the measured tension")
    code = run_bench_config(run_args, config, model_source=lambda _recording, _latency: model)
    if code != 0:
        return None
    return output.with_name(output.stem + ".study.csv")
