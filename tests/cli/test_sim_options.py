"""``rovlink sim``: bad options and configuration files are one-line usage errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli.conftest import RunCli


def test_a_binary_config_file_is_named_not_a_traceback(run_cli: RunCli, tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_bytes(b"\xff\xfe\x00[controller]\n")
    result = run_cli("sim", "--config", str(config))
    assert result.status == 2
    assert result.err == (
        f"rovlink sim: {config}: not UTF-8 text (byte 0xff on line 1), so not a TOML file\n"
    )
    assert "Traceback" not in result.err


def test_a_missing_config_file(run_cli: RunCli, tmp_path: Path) -> None:
    result = run_cli("sim", "--config", str(tmp_path / "none.toml"))
    assert result.status == 2
    assert "none.toml" in result.err
    assert "No such file or directory" in result.err


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--leak-at", "-1"], "argument --leak-at: -1 s is less than the minimum, 0 s"),
        (["--speed", "inf"], "argument --speed: 'inf' is not a number"),
        (["--baud", "0"], "argument --baud/--baudrate: 0 is not a positive integer"),
        (["--tcp", "host:port"], "--tcp: 'host:port' is not HOST:PORT with a port 0–65535"),
    ],
)
def test_bad_options(run_cli: RunCli, option: list[str], message: str) -> None:
    result = run_cli("sim", *option)
    assert result.status == 2
    assert result.err.splitlines()[-1] == f"rovlink sim: error: {message}"
