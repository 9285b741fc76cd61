import socket

from bowden.cli import build_parser, main


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
    assert f"cannot listen on 127.0.0.1:{port}" in capsys.readouterr().err


def test_a_missing_model_file_is_a_clear_error(tmp_path, capsys):
    code = main(["serve", "--store", str(tmp_path / "s.sqlite"), "--model", str(tmp_path / "none.json")])
    assert code == 1
    assert "none.json" in capsys.readouterr().err
