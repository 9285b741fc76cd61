import re
import socket

import pytest

from bowden.cli import build_parser, main
from bowden.model import CompensationModel
from bowden.model.model_file import save_model


def test_serve_is_a_subcommand_with_loopback_default():
    args = build_parser().parse_args(["serve"])
    assert args.host == "127.0.0.1" and args.backend == "sim" and args.handler is not None


def test_a_port_in_use_is_a_clear_error(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        code = main(["serve", "--store", str(tmp_path / "s.sqlite"), "--port", str(port)])
    assert code == 1
    err = capsys.readouterr().err
    assert f"cannot listen on 127.0.0.1:{port}" in err and "--port 0 picks a free port" in err


def test_a_missing_model_file_is_a_clear_error(tmp_path, capsys):
    code = main(["serve", "--store", str(tmp_path / "s.sqlite"), "--model", str(tmp_path / "none.json")])
    assert code == 1
    assert "none.json" in capsys.readouterr().err


# Internal names a message must not show: a class's field (ServeConfig.port) or a field name with
# its unit suffix (time_scale, imu_max_age_s).
INTERNAL = re.compile(r"\b[A-Z]\w+\.\w+|\b[a-z]+(?:_[a-z0-9]+)+\b")
BAD_FLAGS = [
    (["--port", "70000"], "--port must be 0–65535, got 70000"),
    (["--host", ""], "--host must not be empty"),
    (["--rate-hz", "0"], "--rate-hz must be in [1, 2000] Hz, got 0.0"),
    (["--time-scale", "0"], "--time-scale must be in [0.05, 100], got 0.0"),
    (["--friction-k", "-1"], "--friction-k: k = mu*sin(phi/2) must be in [0, 1), got -1.0"),
    (["--repetitions", "0"], "--repetitions must be 1-30, got 0"),
    (["--lead-in", "-1"], "--lead-in must be 0-10 s, got -1.0"),
    (["--break-min", "61"], "--break-min must be 0–60 min, got 61"),
    (["--speeds", "V9"], "--speeds must be distinct speeds of V1, V2, V3"),
    (["--imu-max-age-ms", "0"], "--imu-max-age-ms must be a positive number of milliseconds, got 0"),
    (["--motor-silence-ms", "-1"], "--motor-silence-ms must be a positive number of milliseconds"),
    (["--host-stall-ms", "nan"], "--host-stall-ms must be a positive number of milliseconds"),
    (["--rt-priority", "200"], "--rt-priority must be 1–99 (0: none), got 200"),
    (["--cpu", "-1"], "--cpu must be a CPU number ≥ 0, got -1"),
    (["--backend", "can", "--imu-port", "99999"], "--imu-port must be 1–65535, got 99999"),
    (["--backend", "can", "--calibration-s", "-1"], "--calibration-s must be in (0, 30] s, got -1.0"),
    (["--backend", "can", "--i2c-bus", "-1"], "--i2c-bus must be a bus number ≥ 0, got -1"),
    (["--backend", "can", "--channel", ""], "--channel must not be empty"),
    (["--backend", "can", "--load-cell-gain", "0"], "--load-cell-gain must be finite and non-zero, got 0.0"),
    (["--backend", "can", "--slack-timeout", "0"], "--slack-timeout must be positive and finite, got 0.0"),
]


@pytest.mark.parametrize(("flags", "said"), BAD_FLAGS, ids=[" ".join(f) for f, _ in BAD_FLAGS])
def test_a_wrong_flag_is_one_line_naming_the_flag_not_an_internal_name(
    tmp_path, capsys, monkeypatch, flags, said
):
    def accepted(config):
        raise AssertionError(f"{flags} was accepted: the server would start")

    monkeypatch.setattr("bowden.web.server.serve", accepted)
    model = tmp_path / "model.json"
    save_model(CompensationModel.from_friction(k=0.12), model)
    store = tmp_path / "study.db"
    code = main(["serve", "--store", str(store), "--port", "0", "--model", str(model), *flags])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    line = err.removeprefix("bowden: error: ").strip()
    assert line.startswith(said), line
    assert not INTERNAL.search(line), line
    assert not store.exists()  # refused before the store was opened


def test_run_serve_names_its_port_flag(tmp_path, capsys):
    store = str(tmp_path / "study.db")
    code = main(["run", "--backend", "sim", "--serve", "--record", store, "--port", "70000"])
    assert code == 1
    assert capsys.readouterr().err == "bowden: error: --port must be 0–65535, got 70000\n"
