"""``bowden bench run`` refuses bad options in one line, before anything opens; ``bowden bench
simulate`` takes its range options."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bowden.cli import main


def test_the_real_bench_needs_its_load_cell(tmp_path, capsys):
    assert main(["bench", "run", "--backend", "can", "-o", str(tmp_path / "b.csv")]) == 1
    assert "needs the load cell (--i2c-bus N)" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []  # nothing written: the next attempt needs no --resume


def test_a_bench_that_does_not_open_leaves_no_recording(tmp_path, capsys):
    code = main(["bench", "run", "--backend", "can", "--interface", "virtual",
                 "--channel", "nothing-here", "--i2c-bus", "99", "--calibration-s", "0.05",
                 "--imu-port", "0", "-o", str(tmp_path / "b.csv")])
    assert code == 1
    assert "bowden: error:" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_the_mannequin_needs_its_own_can_id(tmp_path, capsys):
    code = main(["bench", "run", "--backend", "can", "--i2c-bus", "1", "--motor-id", "2",
                 "--mannequin-id", "2", "-o", str(tmp_path / "b.csv")])
    assert code == 1
    assert "each motor needs its own CAN id" in capsys.readouterr().err


def test_an_unreachable_pretension_is_refused(tmp_path, capsys):
    code = main(["bench", "run", "--backend", "sim", "--pretension", "50", "-o", str(tmp_path / "b.csv")])
    assert code == 1
    assert "the pretension (50 N) cannot be reached" in capsys.readouterr().err
    assert not (tmp_path / "b.csv").exists()


def test_an_unknown_mannequin_motor_is_named(tmp_path, capsys):
    code = main(["bench", "run", "--backend", "can", "--i2c-bus", "1", "--mannequin-motor", "AK99",
                 "-o", str(tmp_path / "b.csv")])
    assert code == 1
    assert "unknown AK-series motor 'AK99'" in capsys.readouterr().err


def test_a_load_beyond_the_mannequin_motors_peak_is_refused_before_anything_opens(tmp_path, capsys):
    # Issue 26, item 4: the AK80-9 peaks at 18 Nm; 19 Nm is refused by its flag, nothing is written.
    code = main(["bench", "run", "--backend", "sim", "--loads", "2", "19", "-o", str(tmp_path / "b.csv")])
    assert code == 1
    err = capsys.readouterr().err
    assert "--loads 19 Nm: beyond the 18 Nm peak torque of the mannequin's motor (AK80-9" in err
    assert list(tmp_path.iterdir()) == []


def test_the_simulated_bench_takes_the_mannequin_motor_option(tmp_path, capsys):
    # Issue 26, item 6: --mannequin-motor reaches the simulated bench's driver (an unknown one is named).
    code = main(["bench", "run", "--backend", "sim", "--mannequin-motor", "AK99-1",
                 "-o", str(tmp_path / "b.csv")])
    assert code == 1
    assert "unknown AK-series motor 'AK99-1'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_the_simulated_bench_driven_on_a_wrong_mannequin_id_fails_as_on_the_bus(tmp_path, capsys):
    # Issue 26, item 6: the simulated mannequin answers on id 2; a driver set to id 3 hears nothing.
    code = main(["bench", "run", "--backend", "sim", "--mannequin-id", "3", "-o", str(tmp_path / "b.csv")])
    assert code == 1
    err = capsys.readouterr().err
    assert "the mannequin's motor does not answer" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_bench_simulate_takes_the_range_bench_run_takes(tmp_path, capsys):
    # To simulate the protocol a bench ran: --low-deg/--high-deg as bowden bench run's.
    path = tmp_path / "s.csv"
    assert main(["bench", "simulate", "-o", str(path), "--quiet", "--speeds", "2", "--loads", "1",
                 "--repetitions", "1", "--low-deg", "30", "--high-deg", "70"]) == 0
    elevation = np.degrees(pd.read_csv(path)["elevation_rad"].to_numpy())
    assert 65.0 < elevation.max() < 80.0 and 20.0 < elevation.min() < 35.0, (elevation.min(), elevation.max())


def test_the_simulated_bench_runs_the_motor_option_s_model_on_both_ends() -> None:
    # Commit 95368f1: --motor reaches the simulated bench's TDU driver *and* its simulated peer. A
    # mismatch would not show in the replies (the peer's scaling of the command and of its reply
    # cancel), so the torque the simulated TDU applied is read from its received-frame log: 6 Nm
    # packed in the AK70-10's ±25 Nm field and read with the AK60-6's ±15 Nm would apply 3.6 Nm.
    from bowden.cli import build_parser
    from bowden.cli._bench_run import _open
    from bowden.hardware.motors import motor_limits
    from bowden.sim.peers.ak60_peer import COMMAND

    args = build_parser().parse_args(["bench", "run", "--backend", "sim", "--motor", "AK70-10",
                                      "-o", "unused.csv"])
    with _open(args) as backend:
        config = backend.motor.config
        assert (config.limits, config.torque_limit_nm) == (motor_limits("AK70-10"), 25.0)
        backend.motor.enable()
        for _ in range(500):  # until a command of ours is answered (a busy host may delay the peer)
            backend.motor.command_torque(6.0)
            if backend.motor.poll(0.01) is not None:
                break
        applied = [frame.torque_nm for frame in backend.simulation.received_frames()
                   if frame.kind == COMMAND]
        backend.motor.command_torque(0.0)
    assert applied and applied[-1] == pytest.approx(6.0, abs=25.0 / 2047)  # one step of the 12-bit field


def test_bad_options_of_the_later_segments_are_one_line_before_anything_opens(tmp_path, capsys):
    for options, named in ((["--study-supports", "half"], "--study-supports: 'half'"),
                           (["--study-supports", "1.5"], "--study-supports: 1.5"),
                           (["--study-repetitions", "1"], "--study-repetitions must be in [2, 50]"),
                           (["--chirp-s", "0.5"], "--chirp-s must be in [2, 120] s")):
        code = main(["bench", "run", "--backend", "sim", "-o", str(tmp_path / "b.csv"), *options])
        err = capsys.readouterr().err
        assert code == 1 and named in err and "Traceback" not in err, err
        assert len(err.strip().splitlines()) == 1
    assert not (tmp_path / "b.csv").exists()


def test_bench_validate_on_the_real_bench_needs_its_load_cell(tmp_path, capsys):
    from bowden.model import CompensationModel
    from bowden.model.model_file import save_model

    save_model(CompensationModel.from_friction(k=0.1), tmp_path / "model.json")
    code = main(["bench", "validate", str(tmp_path / "model.json"), "--backend", "can"])
    err = capsys.readouterr().err
    assert code == 1 and "bench validate --backend can needs the load cell (--i2c-bus N)" in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]
    # The refit runs on a bench and from a recording too (tests/runtime/test_bench_fit_sim.py), but a
    # model without a dynamic compensation has nothing to refit: said before anything runs.
    for where in (["--recording", str(tmp_path / "x.csv")], ["--backend", "sim-wire"]):
        code = main(["bench", "validate", str(tmp_path / "model.json"), *where, "--fit"])
        err = capsys.readouterr().err
        assert code == 1 and "--fit: " in err and "has no dynamic compensation to refit" in err, err
        assert len(err.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json"]
