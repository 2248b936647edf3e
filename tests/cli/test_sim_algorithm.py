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


@pytest.mark.parametrize("url", ["sim://?realtime=0", "sim://?realtime=0&algorithm=sum8"])
def test_check_checks_a_simulated_controller_in_the_algorithm_asked(
    run_cli: RunCli, url: str
) -> None:
    # Before, the simulated controller stayed on crc8 (or the URL's): 42 of 51 checks passed.
    algorithm = "sum8" if "algorithm" in url else "xor"
    options = ("--algorithm", algorithm) if algorithm == "xor" else ()
    result = run_cli("check", url, *options, "--only", "checksum-replies")
    assert result.status == 0, result.out + result.err
    assert "1 of 1 checks passed" in result.out
    refused = run_cli("check", "sim://?algorithm=sum8", "--algorithm", "xor", "--only", "query")
    assert refused.status == 2
    assert "the simulated controller's algorithm is sum8, not xor" in refused.err


@pytest.mark.parametrize("algorithm", ["xor", "sum8"])
def test_a_simulated_controller_behind_fault_takes_the_algorithm_given(
    run_cli: RunCli, algorithm: str
) -> None:
    url = "fault://?inner=sim%3A%2F%2F%3Frealtime%3D0&seed=1"
    result = run_cli("send", url, "--checksum", "--algorithm", algorithm, "qd")
    assert result.status == 0, result.err  # (before: not in checksum mode with xor)
    assert "depth_cm=" in result.out
    # Named in the inner URL, it is the host's too.
    named = url.replace("realtime%3D0", f"realtime%3D0%26algorithm%3D{algorithm}")
    result = run_cli("send", named, "--checksum", "qd")
    assert result.status == 0, result.err
    assert "depth_cm=" in result.out


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
