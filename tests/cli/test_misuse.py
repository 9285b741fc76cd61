"""Bad input as a hurried lab gives it (scripts/cli_misuse.py found these): one line naming the flag.

Each case is refused before any simulation or device runs, so the tests call :func:`bowden.cli.main`
in-process and take well under a second each.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pytest

from bowden.cli import main

PNG = b"\x89PNG\r\n\x1a\n" + bytes(range(256))


def refusal(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """The one stderr line of a refused ``bowden`` command line (exit code 1, nothing else on stderr)."""
    code = main(list(argv))
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert code == 1, err
    assert len(lines) == 1, err
    assert lines[0].startswith("bowden: error: "), err
    return lines[0]


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_bench_validate_refuses_a_negative_seed_naming_it(capsys, tmp_path):
    # Was a numpy traceback from deep inside the simulated bench.
    model = tmp_path / "model.json"
    assert main(["bench", "simulate", "-o", str(tmp_path / "b.csv"), "--speeds", "1", "2", "--loads", "1",
                 "2", "--repetitions", "1", "--quiet"]) == 0
    assert main(["identify", str(tmp_path / "b.csv"), "-o", str(model), "--paper-only"]) == 0
    capsys.readouterr()
    line = refusal(capsys, "bench", "validate", str(model), "--seed", "-1")
    assert "--seed must be an integer in [0, " in line


def test_bench_simulate_refuses_a_negative_seed_naming_the_flag(capsys, tmp_path):
    line = refusal(capsys, "bench", "simulate", "-o", str(tmp_path / "b.csv"), "--seed", "-1")
    assert "--seed must be" in line


def test_emg_import_refuses_a_binary_channel_map_in_one_line(capsys, tmp_path):
    # Was a UnicodeDecodeError traceback.
    (tmp_path / "map.png").write_bytes(PNG)
    (tmp_path / "emg.csv").write_text("time_s,biceps\n0,0\n0.0005,0\n")
    line = refusal(capsys, "emg", "import", str(tmp_path / "study.db"), str(tmp_path / "emg.csv"),
                   "--channels", str(tmp_path / "map.png"))
    assert "channel map" in line and "not JSON" in line


def test_bench_simulate_checks_its_output_before_simulating(capsys):
    # /proc takes no new files: the refusal used to come after the whole simulation (its progress lines).
    line = refusal(capsys, "bench", "simulate", "-o", "/proc/bowden-bench.csv")
    assert "cannot write the bench recording (-o) to /proc/bowden-bench.csv" in line


def test_bench_simulate_refuses_a_latency_out_that_is_its_output(capsys, tmp_path):
    # Was accepted: the latency segment then overwrote the bench recording just written.
    output = tmp_path / "bench.csv"
    output.write_text("a recording\n")
    before = digest(output)
    line = refusal(capsys, "bench", "simulate", "-o", str(output), "--latency-out", str(output))
    assert "--latency-out" in line and "-o recording" in line
    assert digest(output) == before


def test_bench_simulate_checks_latency_out_before_simulating(capsys, tmp_path):
    line = refusal(capsys, "bench", "simulate", "-o", str(tmp_path / "b.csv"),
                   "--latency-out", str(tmp_path / "missing" / "l.csv"))
    assert "--latency-out" in line and "does not exist" in line
    assert not (tmp_path / "b.csv").exists()


@pytest.mark.parametrize(("flags", "named"), [
    (["--speeds", "0"], "--speeds"),
    (["--speeds", "nan"], "--speeds"),
    (["--loads", "-1"], "--loads"),
    (["--repetitions", "0"], "--repetitions"),
    (["--low-deg", "110", "--high-deg", "20"], "--low-deg and --high-deg"),
    (["--high-deg", "500"], "--low-deg and --high-deg"),
    (["--low-deg", "nan"], "--low-deg and --high-deg"),
])
def test_bench_simulate_names_the_protocol_flags(capsys, tmp_path, flags, named):
    line = refusal(capsys, "bench", "simulate", "-o", str(tmp_path / "b.csv"), *flags)
    assert named in line
    assert "BenchProtocol" not in line and "_rad" not in line


@pytest.mark.parametrize(("flags", "named"), [
    (["--max-tension", "0"], "--max-tension"),
    (["--pretension", "-1"], "--pretension"),
    (["--spool-radius", "0"], "--spool-radius"),
    (["--speeds", "-2"], "--speeds"),
    (["--kp", "-1"], "--kp and --kd"),
])
def test_bench_run_names_the_bench_flags(capsys, tmp_path, flags, named):
    # Refused before the simulated bench is opened.
    line = refusal(capsys, "bench", "run", "--backend", "sim", "-o", str(tmp_path / "b.csv"), *flags)
    assert named in line
    assert "BenchSafety" not in line and "SlackTakeUp" not in line and "BenchProtocol" not in line


@pytest.mark.parametrize(("flags", "named"), [
    (["--pulley-radius-mm", "0"], "--pulley-radius-mm"),
    (["--pulley-radius-mm", "nan"], "--pulley-radius-mm"),
    (["--cutoff-hz", "-5"], "--cutoff-hz"),
    (["--cutoff-hz", "inf"], "--cutoff-hz"),
    (["--min-elevation-deg", "90", "--max-elevation-deg", "20"], "--min-elevation-deg (90)"),
    (["--min-speed-deg-s", "-1"], "--min-speed-deg-s"),
    (["--max-acceleration-deg-s2", "0"], "--max-acceleration-deg-s2"),
    (["--min-samples", "0"], "--min-samples"),
])
def test_identify_names_its_flags_in_their_units(capsys, tmp_path, flags, named):
    # The settings' own checks said pulley_radius_m, cutoff_hz, min_elevation_rad (in radians).
    bench = tmp_path / "bench.csv"
    bench.write_text("time_s,motor_torque_nm,motor_velocity_rad_s,tension_n,elevation_rad\n0,0,0,0,0\n")
    line = refusal(capsys, "identify", str(bench), "-o", str(tmp_path / "m.json"), *flags)
    assert named in line
    assert "_rad" not in line and "_hz" not in line and "_m " not in line and "per_direction" not in line


@pytest.mark.parametrize(("flags", "named"), [
    (["--participants", "0"], "--participants must"),
    (["--repetitions", "0"], "--repetitions must"),
    (["--seed", "-1"], "--seed must"),
    (["--workers", "0"], "--workers must"),
])
def test_study_names_its_flags(capsys, tmp_path, flags, named):
    line = refusal(capsys, "study", "--out", str(tmp_path / "study"), *flags)
    assert named in line


@pytest.mark.parametrize(("flags", "named"), [
    (["--participants", "0"], "--participants must"),
    (["--repetitions", "-1"], "--repetitions must"),
    (["--seeds", "-1"], "--seeds must"),
    (["--speeds", "V9"], "--speeds: unknown"),
    (["--workers", "0"], "--workers must"),
])
def test_sweep_names_its_flags(capsys, tmp_path, flags, named):
    pytest.importorskip("dask")
    line = refusal(capsys, "sweep", "blend-velocity", "--out", str(tmp_path / "sweep"), *flags)
    assert named in line


@pytest.mark.parametrize("content", [PNG, b"SQLite format 3\x00" + bytes(2000)])
def test_check_fails_a_record_that_is_not_a_study_store(tmp_path, content):
    # bowden check said "ok store: img.png writable" and bowden run then refused the file at the trial.
    from bowden.cli.check import _store

    record = tmp_path / "study.db"
    record.write_bytes(content)
    check = _store(record, session_s=60.0, rate_hz=500.0)
    assert not check.ok
    assert check.message.startswith(f"--record {record}: ")
    assert record.read_bytes() == content


def test_check_fails_a_record_that_is_a_directory(tmp_path):
    from bowden.cli.check import _store

    check = _store(tmp_path, session_s=60.0, rate_hz=500.0)
    assert not check.ok and "is a directory" in check.message


def test_check_passes_a_new_store_and_a_bowden_one(tmp_path):
    import sqlite3

    from bowden.cli.check import _store
    from bowden.store.schema import create_schema

    assert _store(tmp_path / "new.db", session_s=60.0, rate_hz=500.0).ok
    with sqlite3.connect(tmp_path / "study.db") as connection:
        create_schema(connection)
    connection.close()
    assert _store(tmp_path / "study.db", session_s=60.0, rate_hz=500.0).ok


@pytest.mark.parametrize(("flags", "named"), [
    (["--lsl-wait", "5"], "--lsl-wait waits for a recorder of the --lsl streams"),
    (["--lsl-wait", "nan", "--lsl"], "--lsl-wait must be"),
    (["--lsl-wait", "-1", "--lsl"], "--lsl-wait must be"),
    (["--slack-timeout", "-1"], "--slack-timeout"),
    (["--slack-timeout", "nan"], "--slack-timeout"),
])
def test_run_refuses_sync_and_slack_flags_it_used_to_ignore(capsys, flags, named):
    # Each ran the trial (--lsl-wait without --lsl waited for nothing; the simulated suit takes up no
    # slack, so its --slack-timeout was never read). --duration keeps a regression short.
    line = refusal(capsys, "run", "--backend", "sim", "--duration", "0.2", *flags)
    assert named in line


def test_run_names_imu_sender_without_the_ngimu_config(capsys):
    line = refusal(capsys, "run", "--backend", "sim", "--duration", "0.2", "--imu-sender", "1.2.3.4:99999")
    assert line == "bowden: error: --imu-sender port must be an integer 1–65535, got 99999"
    line = refusal(capsys, "run", "--backend", "sim", "--duration", "0.2", "--imu-sender", "not-an-ip")
    assert line.startswith("bowden: error: --imu-sender must be an IP address") and "NgimuConfig" not in line


def test_run_refuses_a_cpu_the_machine_does_not_have(capsys):
    # Was run unpinned, with "CPU {4096}: Invalid argument" among the real-time settings.
    line = refusal(capsys, "run", "--backend", "sim", "--duration", "0.2", "--cpu", "4096")
    assert "--cpu 4096: this machine has CPUs 0–" in line


@pytest.mark.parametrize("hz", ["55", "nan", "0", "-50"])
def test_export_refuses_a_mains_frequency_other_than_50_or_60(capsys, tmp_path, hz):
    # 55 (a typo for 50) was written into every _emg.json as the PowerLineFrequency.
    import sqlite3

    from bowden.store.schema import configure_connection, create_schema

    store = tmp_path / "study.db"
    with sqlite3.connect(store) as connection:
        configure_connection(connection)
        create_schema(connection)
    connection.close()
    line = refusal(capsys, "export", str(store), "--bids", str(tmp_path / "bids"), "--power-line-hz", hz)
    assert "--power-line-hz must be 50 or 60" in line
    assert not (tmp_path / "bids").exists()


def test_run_says_a_record_that_is_a_directory_in_the_flags_words(capsys, tmp_path):
    # Was SQLite's "cannot open the study store DIR: unable to open database file" (no flag named).
    line = refusal(capsys, "run", "--backend", "sim", "--duration", "0.2", "--record", str(tmp_path))
    assert line == (f"bowden: error: cannot write the study store (--record) to {tmp_path}: "
                    "it is a directory; give a file name")


@pytest.mark.parametrize(("store", "says"), [
    (".", "it is a directory"),
    ("missing/study.db", "the folder"),
])
def test_serve_says_a_store_it_cannot_make_in_the_flags_words(capsys, tmp_path, store, says):
    pytest.importorskip("starlette")
    line = refusal(capsys, "serve", "--store", str(tmp_path / store))
    assert "the study store (--store)" in line and says in line


@pytest.mark.parametrize("flags", [["--host", "0.0.0.0"], ["--port", "9999"]])
def test_run_refuses_host_and_port_without_serve(capsys, flags):
    # Were ignored: the trial ran and nothing listened where the operator's browser was pointed.
    line = refusal(capsys, "run", "--backend", "sim", "--duration", "0.2", *flags)
    assert "--host and --port say where --serve listens" in line


@pytest.fixture
def paper_model(tmp_path):
    from bowden.model import CompensationModel
    from bowden.model.model_file import save_model

    path = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), path)
    return path


@pytest.mark.parametrize(("flags", "says"), [
    (["--resume"], "--resume: for a run over the wires"),
    (["--study-repetitions", "3"], "--study-repetitions: for a run over the wires"),
    (["--study-speeds", "V1"], "--study-speeds: for a run over the wires"),
    (["--bench-output", "v.csv"], "--bench-output: for a run over the wires"),
    (["--recording", "x.study.csv", "--study-speeds", "V1"], "--study-speeds: --recording judges"),
])
def test_bench_validate_refuses_wire_run_flags_where_no_run_is_over_the_wires(capsys, paper_model, flags,
                                                                             says):
    # Were ignored: the batch simulated bench validated (seconds) with its own speeds and repetitions.
    line = refusal(capsys, "bench", "validate", str(paper_model), "--support", "0.5", *flags)
    assert says in line


def test_bench_validate_refuses_o_before_validating(capsys, paper_model, tmp_path):
    # A model without the dynamic part was validated first (seconds), then -o refused.
    code = main(["bench", "validate", str(paper_model), "--support", "0.5", "-o", str(tmp_path / "m.json")])
    captured = capsys.readouterr()
    assert code == 1 and captured.out == ""  # no validation table: refused first
    assert captured.err.strip().endswith("has no dynamic compensation to recommend or not")


def test_bench_run_refuses_later_segment_flags_with_no_later_segments(capsys, tmp_path):
    # --chirp-s and --study-* were ignored: the run had no later segments, as asked, and none of theirs.
    line = refusal(capsys, "bench", "run", "--backend", "sim", "-o", str(tmp_path / "b.csv"), "--speeds", "6",
                   "--loads", "1", "--repetitions", "1", "--no-later-segments", "--chirp-s", "5",
                   "--study-speeds", "V1")  # a regression runs two short strokes
    assert "--chirp-s, --study-speeds: the later segments' settings" in line
    assert not (tmp_path / "b.csv").exists()


def test_bench_validate_refuses_fit_of_a_model_without_the_dynamic_part(capsys, paper_model):
    # The batch bench returned the model unchanged and validated it as if refitted (exit 0).
    line = refusal(capsys, "bench", "validate", str(paper_model), "--support", "0.5", "--fit")
    assert line.endswith("has no dynamic compensation to refit")


@pytest.mark.parametrize(("flags", "says"), [
    (["--max-drift-ppm", "-1"], "--max-drift-ppm must be positive, got -1"),
    (["--max-drift-ppm", "0"], "--max-drift-ppm must be positive, got 0"),
    (["--max-drift-ppm", "inf"], "--max-drift-ppm must be positive, got inf"),
    (["--max-residual-ms", "nan"], "--max-residual-ms must be positive, got nan"),
    (["--max-residual-ms", "-0.5"], "--max-residual-ms must be positive, got -0.5"),
    (["--csv-volts-per-unit", "0"], "--csv-volts-per-unit must be positive, got 0"),
    (["--csv-volts-per-unit", "nan"], "--csv-volts-per-unit must be positive, got nan"),
    (["--trigger-bit", "-1"], "--trigger-bit must be 0–31, got -1"),
    (["--trigger-bit", "99"], "--trigger-bit must be 0–31, got 99"),
    (["--rate", "0"], "--rate must be a positive rate in Hz, got 0"),
])
def test_emg_import_checks_its_flags_before_opening_anything(capsys, tmp_path, flags, says):
    # The four were checked only once the store was opened and the recording read (the store's or the
    # file's problem was reported instead, or the bad value after a long read). Neither path exists
    # here: the flag's refusal must come first.
    line = refusal(capsys, "emg", "import", str(tmp_path / "missing.db"), str(tmp_path / "missing.edf"),
                   *flags)
    assert line == f"bowden: error: {says}"


def test_emg_import_checks_its_flags_before_reading_a_recording(capsys, tmp_path):
    # A bowden store with no trial and a recording that is no CSV: either would be refused once opened.
    from bowden.store.study_store import StudyStore

    with StudyStore(tmp_path / "study.db"):
        pass
    (tmp_path / "emg.csv").write_bytes(PNG)
    line = refusal(capsys, "emg", "import", str(tmp_path / "study.db"), str(tmp_path / "emg.csv"),
                   "--trigger-channel", "TRIGGERS", "--max-residual-ms", "0")
    assert line == "bowden: error: --max-residual-ms must be positive, got 0"


@pytest.mark.parametrize("flag", ["--max-drift-ppm", "--max-residual-ms", "--csv-volts-per-unit", "--rate"])
def test_emg_import_names_a_flag_that_is_no_number(capsys, tmp_path, flag):
    with pytest.raises(SystemExit) as exited:
        main(["emg", "import", str(tmp_path / "missing.db"), str(tmp_path / "missing.edf"), flag, "abc"])
    err = capsys.readouterr().err
    assert exited.value.code == 2
    assert f"argument {flag}: invalid float value: 'abc'" in err and "Traceback" not in err


def test_bench_run_says_a_missing_folder_does_not_exist(capsys, tmp_path):
    # Was "cannot write the bench recording to nodir/x.csv: nodir is not a directory" (the writer's
    # check, after the bench was opened); now the commands' shared check, naming -o, before it opens.
    output = tmp_path / "nodir" / "x.csv"
    line = refusal(capsys, "bench", "run", "--backend", "sim", "-o", str(output))
    assert line == (f"bowden: error: cannot write the bench recording (-o) to {output}: "
                    f"the folder {output.parent} does not exist")
    assert not output.parent.exists()


def test_bench_run_says_a_folder_that_is_a_file_is_not_a_directory(capsys, tmp_path):
    (tmp_path / "afile").write_text("not a folder\n")
    output = tmp_path / "afile" / "x.csv"
    line = refusal(capsys, "bench", "run", "--backend", "sim", "-o", str(output))
    assert line.endswith(f"the folder {output.parent} is not a directory")


def test_bench_validate_names_bench_output_of_a_missing_folder(capsys, paper_model, tmp_path):
    output = tmp_path / "nodir" / "v.csv"
    line = refusal(capsys, "bench", "validate", str(paper_model), "--backend", "sim-wire", "--bench-output",
                   str(output))
    assert line == (f"bowden: error: cannot write the bench recording (--bench-output) to {output}: "
                    f"the folder {output.parent} does not exist")


BENCH_HEADER = "time_s,motor_torque_nm,motor_velocity_rad_s,tension_n,elevation_rad"


def test_identify_names_the_columns_of_a_file_of_other_columns_in_one_line(capsys, tmp_path):
    # Was seven lines (one per problem) ending in "allow_extra_columns=True, or --ignore-extra-columns",
    # where ignoring the extra columns could not help: every column of the contract is missing.
    other = tmp_path / "other.csv"
    other.write_text("a,b,c\n1,2,3\n4,5,6\n")
    line = refusal(capsys, "identify", str(other), "-o", str(tmp_path / "m.json"))
    assert line == (f"bowden: error: bench recording {other}: missing column(s) time_s, motor_torque_nm, "
                    "motor_velocity_rad_s, tension_n, elevation_rad; unexpected column(s) 'a' (column 1), "
                    "'b' (column 2), 'c' (column 3)")


def test_identify_names_ignore_extra_columns_where_it_helps_and_shortens_many(capsys, tmp_path):
    bench = tmp_path / "bench.csv"
    extra = [f"extra{i}" for i in range(7)]
    bench.write_text(f"{BENCH_HEADER},{','.join(extra)}\n0,0,0,0,0{',1' * 7}\n")
    line = refusal(capsys, "identify", str(bench), "-o", str(tmp_path / "m.json"))
    assert line == (f"bowden: error: bench recording {bench}: unexpected column(s) 'extra0' (column 6), "
                    "'extra1' (column 7), 'extra2' (column 8), 'extra3' (column 9) and 3 more "
                    "(give --ignore-extra-columns to ignore them)")
    assert "allow_extra_columns" not in line


def test_identify_keeps_the_rename_hint_of_a_column_in_its_one_line(capsys, tmp_path):
    bench = tmp_path / "bench.csv"
    bench.write_text(BENCH_HEADER.replace("tension_n", "tension") + "\n0,0,0,0,0\n")
    line = refusal(capsys, "identify", str(bench), "-o", str(tmp_path / "m.json"))
    assert line.endswith("missing column(s) tension_n (found 'tension': rename it?); "
                         "unexpected column(s) 'tension' (column 4)")
    assert "--ignore-extra-columns" not in line  # ignoring 'tension' leaves tension_n missing


def test_identify_lists_other_problems_of_a_recording_as_before(capsys, tmp_path):
    # Only the columns' problem is one line: a file with the contract's columns still gets every
    # problem named by row (docs/identification.md), as the library raises it.
    bench = tmp_path / "bench.csv"
    bench.write_text(f"{BENCH_HEADER}\n0,0,0,0,0\n0,0,0,x,0\n")
    assert main(["identify", str(bench), "-o", str(tmp_path / "m.json")]) == 1
    err = capsys.readouterr().err
    assert "'x' is not a number" in err and "Traceback" not in err


def test_the_library_keeps_every_column_problem_for_its_callers(tmp_path):
    from bowden.errors import RecordingError
    from bowden.identify.recording import read_bench_recording
    from bowden.identify.validation import BenchColumnsError

    other = tmp_path / "other.csv"
    other.write_text("a,b,c\n1,2,3\n")
    with pytest.raises(BenchColumnsError) as raised:
        read_bench_recording(other)
    assert isinstance(raised.value, RecordingError)
    assert str(raised.value).count("\n  - ") == 6 and "allow_extra_columns=True" in str(raised.value)
    assert raised.value.unexpected == ((1, "a"), (2, "b"), (3, "c"))
    assert [name for name, _ in raised.value.missing] == ["time_s", "motor_torque_nm", "motor_velocity_rad_s",
                                                          "tension_n", "elevation_rad"]


@pytest.mark.parametrize(("flags", "named"), [
    (["--imu-latency-ms", "30"], "--imu-latency-ms: "),
    (["--imu-latency-ms", "50"], "--imu-latency-ms: "),  # the default's value, given: still ignored
    (["--latency-recording", "latency.csv"], "--latency-recording: "),
    (["--imu-latency-ms", "30", "--latency-recording", "latency.csv"],
     "--imu-latency-ms, --latency-recording: "),
])
def test_identify_refuses_latency_flags_that_paper_only_ignores(capsys, tmp_path, flags, named):
    # --paper-only --imu-latency-ms 30 wrote the paper's lines and said nothing: only the dynamic
    # compensation's estimator takes the IMU's latency. Refused before the recording is read (it
    # does not exist here).
    line = refusal(capsys, "identify", str(tmp_path / "bench.csv"), "-o", str(tmp_path / "m.json"),
                   "--paper-only", *flags)
    assert line == (f"bowden: error: {named}the dynamic compensation's IMU latency, which --paper-only "
                    "leaves out (the paper's lines take none)")


def test_identify_refuses_a_study_recording_that_paper_only_cannot_use(capsys, tmp_path):
    # --paper-only --study-recording X read and judged X, then "recommended nothing": the recording
    # chooses between the paper's lines and the dynamic compensation, which --paper-only leaves out.
    line = refusal(capsys, "identify", str(tmp_path / "bench.csv"), "-o", str(tmp_path / "m.json"),
                   "--paper-only", "--study-recording", str(tmp_path / "bench.study.csv"))
    assert line == ("bowden: error: --study-recording chooses where the dynamic compensation runs, "
                    "which --paper-only leaves out")


def test_identify_refuses_imu_latency_ms_beside_the_latency_recording_that_replaces_it(capsys, tmp_path):
    # The latency identified from the segment silently replaced the one given.
    line = refusal(capsys, "identify", str(tmp_path / "bench.csv"), "-o", str(tmp_path / "m.json"),
                   "--imu-latency-ms", "30", "--latency-recording", str(tmp_path / "latency.csv"))
    assert "--imu-latency-ms and --latency-recording both set the IMU latency" in line


def test_identify_checks_its_degree_flags_before_reading_the_latency_recording(capsys, tmp_path):
    # The latency segment (a missing file here) used to be read first.
    line = refusal(capsys, "identify", str(tmp_path / "bench.csv"), "-o", str(tmp_path / "m.json"),
                   "--latency-recording", str(tmp_path / "latency.csv"), "--min-speed-deg-s", "-1")
    assert "--min-speed-deg-s" in line
