"""``bowden bench validate MODEL --backend can|sim-wire``: the study-like segment on a bench in real time.

Private to the CLI. The bench runs only the protocol's study-like strokes (docs/identification.md,
"The protocol, exactly", segment 3) with MODEL's compensations in turn — the slack taken up first, no
identification strokes, no chirp — recorded crash-safe like ``bench run`` (``--resume``). With
``--fit`` the study-like fit's blocks run first (:class:`~bowden.protocol.bench.StudyFit`: the batch
fit's grid and repetitions, :mod:`bowden.identify.study_fit`), and the study-like blocks after them run
the candidate the recorded fit chose (:func:`bowden.identify.study_recording.choose_fitted`).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from bowden.cli._bench_run import bench_config, run_bench_config, study_strokes
from bowden.errors import ParameterError, RecordingError
from bowden.model import CompensationModel
from bowden.model.model_record import controller_sha256
from bowden.protocol.bench import StudyFit
from bowden.runtime.bench_config import BenchRunConfig
from bowden.runtime.bench_recording import journal_model, journal_path, read_journal


def _say(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def default_fit(args: argparse.Namespace) -> StudyFit:
    """The batch fit's blocks on a bench: at ``--support`` (default 0.5, as the batch fit), the
    ``--study-speeds`` (default V1-V3), every candidate of the grid, its repetitions."""
    from bowden.contracts import SPEEDS
    from bowden.identify.study_fit import FIT_REPETITIONS, fit_grid

    return StudyFit(grid=fit_grid(), support=0.5 if args.support is None else args.support,
                    speeds=tuple(args.study_speeds) if args.study_speeds else tuple(SPEEDS),
                    repetitions=FIT_REPETITIONS)


class GridModels:
    """The fit's models from :mod:`bowden.identify.study_fit`'s grid (``BenchRun``'s ``fit_models``)."""

    def __init__(self, flag: str) -> None:
        self.flag = flag

    def candidate(self, model: CompensationModel, index: int) -> CompensationModel:
        from bowden.identify.study_fit import fit_candidate

        return fit_candidate(model, index)

    def chosen(self, model: CompensationModel, study_recording: Path) -> CompensationModel:
        from bowden.identify.study_recording import choose_fitted

        choice = choose_fitted(model, study_recording, self.flag)
        _say(f"the fit chose candidate {choice.candidate} (study cost {choice.costs[choice.candidate]:.3f}); "
             "the study-like blocks run it")
        return choice.model


def run_study_on_bench(args: argparse.Namespace, model: CompensationModel,
                       supports: tuple[float | str, ...], fit: StudyFit | None = None) -> Path | int:
    """Run the study-like blocks of ``model`` on the bench of ``args`` (the ``fit``'s first, if any);
    the study recording's path, or the exit code when the bench stopped (said on stderr)."""
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
    config = replace(config, identification=False, latency=None, study=study, fit=fit,
                     model_digest=controller_sha256(model))
    if run_args.backend == "can" and args.i2c_bus is None:
        raise ParameterError("bowden bench validate --backend can needs the load cell (--i2c-bus N): it "
                             "judges the compensations against the measured tension")
    if fit is not None:
        _say(estimate(config, blocks_done=_blocks_done(run_args, config)))
    code = run_bench_config(run_args, config, model_source=lambda _recording, _latency: model,
                            fit_models=GridModels("--bench-output"), output_flag="--bench-output")
    if code != 0:
        return code
    return output.with_name(output.stem + ".study.csv")


def _blocks_done(args: argparse.Namespace, config: BenchRunConfig) -> int:
    """The study-like blocks a ``--resume`` finds recorded (its journal's units done after the units
    before the blocks); 0 without ``--resume``, or when the journal is of another protocol (the run
    is then refused before the bench moves)."""
    journal = read_journal(args.output) if args.resume else None
    if journal is None or journal.get("protocol") != config.protocol_fingerprint():
        return 0
    before_blocks = config.n_units - len(config.study_blocks())
    return max(0, int(journal["strokes_done"]) - before_blocks)


def estimate(config: BenchRunConfig, *, blocks_done: int = 0) -> str:
    """How many blocks and cycles the fit and the validation run, and roughly how long on the bench;
    after ``blocks_done`` blocks (a resumed run), what is left of each."""
    from bowden.runtime.bench_segments import study_time_s

    fit, study = config.fit, config.study
    assert fit is not None and study is not None
    blocks = config.study_blocks()
    left = blocks[blocks_done:]
    fitting = [(block, strokes) for block, strokes in left if block.fit]
    validating = [(block, strokes) for block, strokes in left if not block.fit]
    if blocks_done:
        return (f"bench validate --fit, resumed with {blocks_done} of {len(blocks)} blocks done: the fit's "
                f"{len(fitting)} blocks left, about {study_time_s(fitting) / 60:.0f} min; then the "
                f"validation {len(validating)} blocks, about {study_time_s(validating) / 60:.0f} min; about "
                f"{study_time_s(left) / 60:.0f} min left")
    speeds = " ".join(fit.speeds)
    return (f"bench validate --fit: the fit runs {len(fitting)} blocks ({len(fitting) * fit.repetitions} "
            f"cycles: support {fit.support}, {speeds}, the paper's and {len(fit.candidates)} candidates, "
            f"{fit.repetitions} cycles each), about {study_time_s(fitting) / 60:.0f} min; then the "
            f"validation {len(validating)} blocks ({len(validating) * study.repetitions} cycles), about "
            f"{study_time_s(validating) / 60:.0f} min; about {study_time_s(blocks) / 60:.0f} min in all")


def check_recorded_model(model: CompensationModel, model_path: Path, study_recording: Path) -> str | None:
    """Refuse a ``--recording`` whose blocks ran another model than MODEL, by the SHA-256 of the
    controller's coefficients its run's journal keeps (``<stem>.csv.journal`` or
    ``<stem>.parquet.journal`` beside ``<stem>.study.csv``); the one line to say when it cannot be told
    (said once the recording was judged: a recording refused gets its one error line alone)."""
    stem = study_recording.name.removesuffix(".study.csv")
    recordings = [study_recording.with_name(stem + suffix) for suffix in (".csv", ".parquet")]
    recording = next((path for path in recordings if journal_path(path).exists()), None)
    unchecked = f"bench validate: the model of --recording {study_recording} could not be checked"
    if stem == study_recording.name or recording is None:
        return f"{unchecked} (no journal of its run beside it): give the MODEL its blocks ran"
    try:
        journal = read_journal(recording)
    except RecordingError as error:
        return f"{unchecked}: {error}"
    recorded = journal_model(journal)
    if recorded is None:
        return (f"{unchecked} ({journal_path(recording).name} keeps none: `bench run` identifies its model "
                "during the run)")
    digest = controller_sha256(model)
    if recorded != digest:
        raise ParameterError(
            f"--recording {study_recording}: its blocks ran another model than MODEL {model_path} (its "
            f"journal keeps the coefficients' SHA-256 {str(recorded)[:12]}…, MODEL's is {digest[:12]}…): "
            "give the model it was recorded with")
    return None


def print_fit(model: CompensationModel, study_recording: Path, flag: str) -> CompensationModel:
    """Print the recorded fit's candidates with their study costs and the one chosen; the model with
    it applied."""
    from bowden.identify.study_fit import fit_grid
    from bowden.identify.study_recording import choose_fitted

    choice = choose_fitted(model, study_recording, flag)
    grid = fit_grid()
    print("candidate  drag scale  inertia scale  lowering shift (Nm)  study cost")
    for candidate, cost in choice.costs.items():
        drag, inertia, shift = grid[candidate]
        print(f"{candidate:9d}  {drag:10g}  {inertia:13g}  {shift:19g}  {cost:10.3f}")
    drag, inertia, shift = grid[choice.candidate]
    print(f"fitted: candidate {choice.candidate} (drag ×{drag:g}, inertia ×{inertia:g}, lowering line "
          f"{shift:+g} Nm): the lowest study cost; validated on the study-like blocks after the fit")
    return choice.model
