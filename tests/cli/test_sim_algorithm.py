"""A ``sim://`` controller checks frames with the algorithm the host was given (``--algorithm``,
``?algorithm=``, a recording's), so that checksum mode works with any of them."""

from __future__ import annotations

from pathlib import Path

import pytest

from rovlink.sim.url import open_url, parse_sim_url, with_algorithm
from tests.cli.conftest import RunCli


@pytest.mark.parametrize("algorithm", ["xor", "sum8", "crc8"])
def test_send_in_checksum_mode_with_the_algorithm_given(run_cli: RunCli, algorithm: str) -> None:
    result = run_cli("send", "sim://?realtime=0", "--checksum", "--algorithm", algorithm, "qd")
    assert result.status == 0, result.err
    assert "depth_cm=" in result.out


def test_the_urls_algorithm_is_the_hosts_without_the_option(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://?algorithm=xor&realtime=0", "--checksum", "#qd!")
    assert result.status == 0, result.err
    assert result.out.splitlines()[0] == "> #qd15!"  # its xor checksum, not crc8's (8C)


def test_an_option_against_the_urls_algorithm_is_a_usage_error(run_cli: RunCli) -> None:
    result = run_cli("send", "sim://?algorithm=xor", "--algorithm", "sum8", "qd")
    assert result.status == 2
    assert result.err.splitlines()[-1] == (
        "rovlink send: error: --algorithm sum8: 'sim://?algorithm=xor': "
        "the simulated controller's algorithm is xor, not sum8"
    )


def test_a_replay_into_sim_uses_the_recordings_algorithm(run_cli: RunCli, tmp_path: Path) -> None:
    recording = tmp_path / "dive.jsonl"
    made = run_cli(
        "send", "sim://?seed=1&realtime=0", "--checksum", "--algorithm", "xor",
        "--record", str(recording), "qd",
    )  # fmt: skip
    assert made.status == 0, made.err
    result = run_cli("replay", str(recording), "--to", "sim://?seed=1&realtime=0")
    assert result.status == 0, result.err
    assert "0 different" in result.out


def test_the_url_option() -> None:
    assert parse_sim_url("sim://?algorithm=sum8").algorithm == "sum8"
    assert parse_sim_url("sim://").algorithm is None
    with pytest.raises(ValueError, match="unknown checksum algorithm 'md5'; known: crc8, sum8"):
        parse_sim_url("sim://?algorithm=md5")
    assert with_algorithm("sim://", "xor") == "sim://?algorithm=xor"
    port = open_url("sim://?algorithm=xor&realtime=0")
    try:
        assert port.controller.config.checksum_algorithm == "xor"
    finally:
        port.close()
