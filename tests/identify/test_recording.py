"""Reading bench recordings: every kind of bad file gets its own error naming column and row."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from bowden.contracts import (
    BENCH_COLUMNS,
    BENCH_ELEVATION,
    BENCH_MOTOR_TORQUE,
    BENCH_MOTOR_VELOCITY,
    BENCH_TENSION,
    BENCH_TIME,
    BENCH_TRIAL,
)
from bowden.errors import ParameterError, RecordingError
from bowden.identify.recording import RecordingLimits, bench_recording_from_frame, read_bench_recording


def good_frame(n: int = 200, rate_hz: float = 100.0) -> pd.DataFrame:
    t = np.arange(n) / rate_hz
    return pd.DataFrame(
        {
            BENCH_TIME: t,
            BENCH_MOTOR_TORQUE: 1.0 + 0.1 * np.sin(t),
            BENCH_MOTOR_VELOCITY: 2.0 * np.cos(t),
            BENCH_TENSION: 30.0 + np.sin(t),
            BENCH_ELEVATION: 0.8 + 0.5 * np.sin(t),
        }
    )


def write_csv(tmp_path: Path, frame: pd.DataFrame, name: str = "bench.csv") -> Path:
    path = tmp_path / name
    frame.to_csv(path, index=False)
    return path


def read_error(tmp_path: Path, frame: pd.DataFrame, **kwargs: object) -> str:
    with pytest.raises(RecordingError) as info:
        read_bench_recording(write_csv(tmp_path, frame), **kwargs)  # type: ignore[arg-type]
    return str(info.value)


def test_good_csv_and_parquet_read_identically(tmp_path: Path) -> None:
    frame = good_frame()
    csv = write_csv(tmp_path, frame)
    parquet = tmp_path / "bench.parquet"
    frame.to_parquet(parquet)
    from_csv = read_bench_recording(csv)
    from_parquet = read_bench_recording(parquet)
    for name in ("time_s", "motor_torque_nm", "motor_velocity_rad_s", "tension_n", "elevation_rad"):
        np.testing.assert_allclose(getattr(from_csv, name), frame[name].to_numpy(), rtol=1e-14)
        np.testing.assert_array_equal(getattr(from_parquet, name), frame[name].to_numpy())
    assert from_csv.sources[0].sha256 == hashlib.sha256(csv.read_bytes()).hexdigest()
    assert from_csv.sources[0].rows == 200
    assert from_csv.n_samples == 200
    assert from_csv.describe_sample(7) == f"row 8 of {csv}"


def test_several_files_and_trials_become_separate_blocks(tmp_path: Path) -> None:
    first = good_frame(100)
    first[BENCH_TRIAL] = ["a"] * 50 + ["b"] * 50
    first.loc[50:, BENCH_TIME] -= first.loc[50, BENCH_TIME]  # each trial restarts its clock
    second = good_frame(80)
    recording = read_bench_recording(
        [write_csv(tmp_path, first, "one.csv"), write_csv(tmp_path, second, "two.csv")]
    )
    assert recording.n_samples == 180
    assert list(np.unique(recording.block)) == [0, 1, 2]
    assert recording.block_labels == (
        f"{tmp_path / 'one.csv'} trial a",
        f"{tmp_path / 'one.csv'} trial b",
        str(tmp_path / "two.csv"),
    )
    assert recording.describe_sample(100) == f"row 1 of {tmp_path / 'two.csv'}"
    assert list(recording.to_frame().columns) == [*BENCH_COLUMNS, BENCH_TRIAL]


def test_missing_column_is_named_with_a_rename_hint(tmp_path: Path) -> None:
    frame = good_frame().rename(columns={BENCH_TENSION: "tension"})
    message = read_error(tmp_path, frame)
    assert "column tension_n is missing" in message
    assert "found 'tension'" in message


def test_extra_column_is_named_with_its_position(tmp_path: Path) -> None:
    frame = good_frame()
    frame["temperature_c"] = 25.0
    message = read_error(tmp_path, frame)
    assert "unexpected column(s) 'temperature_c' (column 6)" in message
    assert "--ignore-extra-columns" in message  # what a command-line user types
    recording = read_bench_recording(tmp_path / "bench.csv", allow_extra_columns=True)
    assert recording.n_samples == 200


@pytest.mark.parametrize("convert", [
    lambda t: pd.to_datetime(t, unit="s"), lambda t: pd.to_timedelta(t, unit="s"),
])
def test_dates_or_durations_as_time_are_named_once(tmp_path: Path, convert) -> None:
    frame = good_frame()
    frame[BENCH_TIME] = convert(frame[BENCH_TIME])
    frame.to_parquet(tmp_path / "bench.parquet")
    with pytest.raises(RecordingError) as info:
        read_bench_recording(tmp_path / "bench.parquet")
    message = str(info.value)
    assert "column time_s holds" in message and "seconds since the start" in message
    assert "1 problem" in message  # not also "milliseconds?" from its nanoseconds


def test_non_numeric_value_names_column_row_and_line(tmp_path: Path) -> None:
    frame = good_frame().astype({BENCH_TENSION: object})
    frame.loc[16, BENCH_TENSION] = "12,5"
    message = read_error(tmp_path, frame)
    assert "column tension_n, row 17 (line 18): '12,5' is not a number" in message


def test_nan_run_names_column_and_row_range(tmp_path: Path) -> None:
    frame = good_frame()
    frame.loc[119:134, BENCH_MOTOR_TORQUE] = np.nan
    frame.loc[150, BENCH_MOTOR_TORQUE] = np.nan
    message = read_error(tmp_path, frame)
    assert "column motor_torque_nm has missing values (NaN) at rows 120–135 (16 rows)" in message
    assert "1 more run(s), 17 missing values in all" in message


def test_infinite_value_is_reported(tmp_path: Path) -> None:
    frame = good_frame()
    frame.loc[3, BENCH_MOTOR_VELOCITY] = np.inf
    frame.to_parquet(tmp_path / "bench.parquet")
    with pytest.raises(RecordingError, match=r"column motor_velocity_rad_s, row 4: infinite value"):
        read_bench_recording(tmp_path / "bench.parquet")


def test_duplicated_time_names_the_row(tmp_path: Path) -> None:
    frame = good_frame()
    frame.loc[42, BENCH_TIME] = frame.loc[41, BENCH_TIME]
    message = read_error(tmp_path, frame)
    assert "column time_s, row 43 (line 44): duplicated time 0.41 s" in message


def test_time_going_backwards_names_the_row_and_suggests_a_trial_column(tmp_path: Path) -> None:
    frame = pd.concat([good_frame(100), good_frame(100)], ignore_index=True)
    message = read_error(tmp_path, frame)
    assert "column time_s, row 101 (line 102): time goes backwards (0 s after 0.99 s)" in message
    assert "add a 'trial' column" in message


def test_trial_split_in_two_blocks_is_reported(tmp_path: Path) -> None:
    frame = good_frame(90)
    frame[BENCH_TRIAL] = [1] * 30 + [2] * 30 + [1] * 30
    message = read_error(tmp_path, frame)
    assert "column trial, row 61 (line 62): trial '1' starts again after other trials" in message


def test_missing_trial_id_is_reported(tmp_path: Path) -> None:
    frame = good_frame(60)
    frame[BENCH_TRIAL] = [1.0] * 30 + [np.nan] + [2.0] * 29
    assert "column trial, row 31 (line 32): missing trial id" in read_error(tmp_path, frame)


def test_elevation_in_degrees(tmp_path: Path) -> None:
    frame = good_frame()
    frame[BENCH_ELEVATION] = np.degrees(frame[BENCH_ELEVATION])
    message = read_error(tmp_path, frame)
    assert "column elevation_rad, row 1 (line 2): 45.8366 exceeds the plausible ±3.14159 rad" in message
    assert "looks like degrees" in message


def test_torque_in_millinewton_metres(tmp_path: Path) -> None:
    frame = good_frame()
    frame[BENCH_MOTOR_TORQUE] *= 1000.0
    message = read_error(tmp_path, frame)
    assert "column motor_torque_nm, row 1 (line 2): 1000 exceeds the plausible ±50 Nm" in message
    assert "mNm" in message


def test_velocity_in_degrees_per_second(tmp_path: Path) -> None:
    frame = good_frame()
    frame[BENCH_MOTOR_VELOCITY] = np.degrees(frame[BENCH_MOTOR_VELOCITY])
    assert "column motor_velocity_rad_s, row 1 (line 2): 114.592 exceeds" in read_error(tmp_path, frame)


def test_tension_in_grams(tmp_path: Path) -> None:
    frame = good_frame()
    frame[BENCH_TENSION] *= 1000.0 / 9.81
    assert "column tension_n, row 1 (line 2): 3058.1 exceeds the plausible ±2000 N" in read_error(
        tmp_path, frame
    )


def test_time_in_milliseconds(tmp_path: Path) -> None:
    frame = good_frame()
    frame[BENCH_TIME] *= 1000.0
    message = read_error(tmp_path, frame)
    assert "column time_s: median sampling interval 10 s (0.1 Hz)" in message
    assert "milliseconds" in message


def test_all_problems_of_a_file_are_listed_together(tmp_path: Path) -> None:
    frame = good_frame()
    frame[BENCH_ELEVATION] = np.degrees(frame[BENCH_ELEVATION])
    frame.loc[5, BENCH_TIME] = frame.loc[4, BENCH_TIME]
    message = read_error(tmp_path, frame)
    assert "2 problems" in message
    assert "elevation_rad" in message and "duplicated time" in message


def test_empty_file_has_no_data_rows(tmp_path: Path) -> None:
    assert "no data rows" in read_error(tmp_path, good_frame().iloc[:0])
    (tmp_path / "blank.csv").write_text("")
    with pytest.raises(RecordingError, match="not a readable CSV file"):
        read_bench_recording(tmp_path / "blank.csv")


def test_unreadable_inputs(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="cannot read it"):
        read_bench_recording(tmp_path / "absent.csv")
    with pytest.raises(RecordingError, match=r"unknown format '\.xlsx'"):
        read_bench_recording(tmp_path / "bench.xlsx")
    (tmp_path / "ragged.csv").write_text(",".join(BENCH_COLUMNS) + "\n1,2,3,4,5\n1,2,3,4,5,6,7\n")
    with pytest.raises(RecordingError, match=r"ragged.csv: not a readable CSV file \(.*line 3"):
        read_bench_recording(tmp_path / "ragged.csv")
    (tmp_path / "fake.parquet").write_text("not parquet")
    with pytest.raises(RecordingError, match="not a readable Parquet file"):
        read_bench_recording(tmp_path / "fake.parquet")


def test_in_memory_table_is_validated_and_hashed_stably() -> None:
    frame = good_frame()
    first = bench_recording_from_frame(frame, name="sim")
    second = bench_recording_from_frame(frame.copy(), name="sim")
    assert first.sources[0].sha256 == second.sources[0].sha256
    changed = frame.copy()
    changed.loc[0, BENCH_TENSION] += 1e-9
    assert bench_recording_from_frame(changed).sources[0].sha256 != first.sources[0].sha256
    with pytest.raises(RecordingError, match="sim: 1 problem"):
        bench_recording_from_frame(frame.drop(columns=[BENCH_TIME]), name="sim")


def test_limits_are_validated_and_configurable(tmp_path: Path) -> None:
    with pytest.raises(ParameterError, match="max_abs_tension_n"):
        RecordingLimits(max_abs_tension_n=-1.0)
    frame = good_frame()
    frame[BENCH_TENSION] *= 100.0
    read_bench_recording(write_csv(tmp_path, frame), limits=RecordingLimits(max_abs_tension_n=5000.0))
