"""Fill numba's cache with the kernels of a study's trial: simulated, encoded for the store, analysed.

Run by tests/conftest.py in the background at the lowest priority while the lanes' first real-time
tests run: on a fresh checkout the first test to analyse a trial compiled these kernels itself, about
17 s of one core (idle; 31 s on a loaded host), and that test is in the suit lane (tests/runtime/
test_cli_run.py), whose wall time is the suite's. At nice 19 it takes only what the lanes leave; a
test that needs a kernel before it is cached compiles it as before. With a warm cache it is 3 s of CPU.

Usage: ``python tests/warm_kernels.py``.
"""

from __future__ import annotations


def warm_up_study_kernels() -> None:
    from bowden import contracts as c
    from bowden.analysis.segmentation import SegmentationParameters
    from bowden.analysis.trial_outcomes import AnalysisParameters, TrialMetadata, analyse_trial
    from bowden.model import CompensationModel
    from bowden.sim.batch import ProtocolSettings, simulate_trial
    from bowden.sim.participants import generate_cohort
    from bowden.store.trial_encoding import encode_trial

    participant = generate_cohort(0, n_participants=2)[0]
    condition, speed = c.CONDITIONS[-1], c.SPEEDS[-1]
    protocol = ProtocolSettings(repetitions=3, lead_in_s=0.5, tail_s=0.2, speeds=(speed,))
    trial = simulate_trial(participant, condition, speed, model=CompensationModel.from_friction(k=0.1),
                           settings=protocol)
    samples, emg = trial.to_pandas(), trial.emg()
    encode_trial(samples.loc[:, list(c.TRIAL_COLUMNS)], emg)
    which = TrialMetadata(participant=participant.participant_id, condition=condition, speed=speed)
    any_count = AnalysisParameters(segmentation=SegmentationParameters(expected_repetitions=None))
    analyse_trial(which, samples, emg, any_count)


if __name__ == "__main__":
    warm_up_study_kernels()
