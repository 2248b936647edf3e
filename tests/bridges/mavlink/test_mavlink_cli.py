"""``rovlink mavlink``: options checked before anything opens, and a real run in a process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.bridges.mavlink.rig import GroundStation, free_udp_port
from tests.cli.conftest import RunCli

_SRC = str(Path(__file__).resolve().parents[3] / "src")


def test_a_bad_endpoint_is_a_usage_error(run_cli: RunCli) -> None:
    result = run_cli("mavlink", "sim://", "--out", "udp://127.0.0.1:14550")
    assert result.status == 2
    assert "expected SCHEME:HOST:PORT" in result.err
    assert result.out == ""


def test_a_bad_parameter_file_is_one_line_naming_the_line(run_cli: RunCli, tmp_path: Path) -> None:
    params = tmp_path / "robot.param"
    params.write_text("RL_DEPTH_P 30\nRL_MAX_PWM 999\n", encoding="utf-8")
    result = run_cli("mavlink", "sim://", "--params", str(params))
    assert result.status == 2
    assert result.err.strip().endswith(
        "robot.param:2: RL_MAX_PWM must be an integer in 0–255, got 999"
    )
    assert len(result.err.strip().splitlines()) == 1
    missing = run_cli("mavlink", "sim://", "--params", str(tmp_path / "none.param"))
    assert missing.status == 2
    assert "none.param: cannot read" in missing.err


def test_a_qgroundcontrol_parameter_file_is_read(run_cli: RunCli, tmp_path: Path) -> None:
    # The first lines are taken (before, line 1 was refused): the error is the one on line 4.
    params = tmp_path / "robot.params"
    params.write_text(
        "# Onboard parameters for Vehicle 1\n1\t1\tRL_DEPTH_P\t33\t6\n"
        "1\t1\tRL_MAX_PWM\t200\t6\n1\t1\tRL_DEPTH_I\t500\t6\n",
        encoding="utf-8",
    )
    result = run_cli("mavlink", "sim://", "--params", str(params))
    assert result.status == 2
    assert result.err.strip().endswith(
        "robot.params:4: RL_DEPTH_I must be an integer in 0–99, got 500"
    )


def test_a_parameter_file_saved_with_a_byte_order_mark_is_read(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # Windows editors save UTF-8 with a byte order mark (and CRLF line ends): line 1 was refused
    # as "no parameter '\\ufeffRL_DEPTH_P'". The error now is the one on line 2.
    params = tmp_path / "robot.param"
    params.write_bytes(b"\xef\xbb\xbfRL_DEPTH_P 30\r\nRL_MAX_PWM 999\r\n")
    result = run_cli("mavlink", "sim://", "--params", str(params))
    assert result.status == 2
    assert result.err.strip().endswith(
        "robot.param:2: RL_MAX_PWM must be an integer in 0–255, got 999"
    )


@pytest.mark.integration
def test_the_command_serves_a_ground_station_and_ends_on_ctrl_c(tmp_path: Path) -> None:
    port = free_udp_port()
    gcs = GroundStation(f"udpin:127.0.0.1:{port}")
    environment = dict(os.environ, PYTHONPATH=_SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    process = subprocess.Popen(
        [sys.executable, "-m", "rovlink", "mavlink", "sim://", "--out", f"udpout:127.0.0.1:{port}"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=environment,
    )
    try:
        heartbeat = gcs.receive("HEARTBEAT", timeout_s=20.0)
        assert heartbeat.type == 12
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=20)
        assert "rovlink mavlink ready" in out
        assert process.returncode == 130, err
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
        gcs.close()
