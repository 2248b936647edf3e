"""A driving command whose recording fails (a full disk) fails too, naming the file, and does not
leave the robot moving: a dive believed recorded was not."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.cli.conftest import RunCli
from tests.cli.test_demo import _fast_sim_url
from tests.client.conftest import REPLY_TIMEOUT_S, wait_until
from tests.client.fake_controller import FakeControllerServer
from tests.terminals import WAIT_S, Terminal

pytestmark = pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")


@pytest.fixture
def full_disk(tmp_path: Path) -> Path:
    """A recording's name whose every write fails with ENOSPC (``/dev/full``)."""
    path = tmp_path / "dive.jsonl"
    path.symlink_to("/dev/full")
    return path


@pytest.fixture
def controller() -> Iterator[FakeControllerServer]:
    server = FakeControllerServer()
    yield server
    server.close()


def _frames(controller: FakeControllerServer) -> list[str]:
    return controller.fakes[0].frames() if controller.fakes else []


def _send(run_cli: RunCli, url: str, recording: Path, *line: str) -> tuple[int, str]:
    result = run_cli(
        "send", url, "--boot-timeout", "0", "--record", str(recording), "--overwrite", *line
    )
    return result.status, result.err


@pytest.mark.integration
def test_send_whose_recording_fails_after_motion_fails_and_stops_the_robot(
    run_cli: RunCli, full_disk: Path, controller: FakeControllerServer
) -> None:
    # Before: status 0, and the robot drove on at 20 % (only an ERROR line in the log said
    # that nothing was recorded).
    status, err = _send(run_cli, controller.url, full_disk, "start", "th 90 20", "qd")
    assert status == 1, err
    expected = f"rovlink send: recording to {full_disk} stopped: No space left on device"
    assert f"{expected} (sent #stop!)\n" in err
    assert wait_until(lambda: controller.fakes[0].frames()[-1:] == ["#stop!"])
    assert controller.fakes[0].frames() == ["#crcoff!", "#start!", "#th.90.20!", "#qd!", "#stop!"]


@pytest.mark.integration
def test_send_whose_recording_fails_without_motion_fails_and_sends_nothing_more(
    run_cli: RunCli, full_disk: Path, controller: FakeControllerServer
) -> None:
    status, err = _send(run_cli, controller.url, full_disk, "qd")
    assert status == 1, err
    assert err.endswith(
        f"rovlink send: recording to {full_disk} stopped: No space left on device\n"
    )
    assert controller.fakes[0].frames() == ["#crcoff!", "#qd!"]


def test_demo_whose_recording_fails_fails_naming_the_file(
    run_cli: RunCli, full_disk: Path, tmp_path: Path
) -> None:
    # (The dive ends locked whatever happens: tests/cli/test_demo.py.)
    dive = ["--depth", "20", "--hold", "0", "--leg", "0.05", "--reach-timeout", "20"]
    link = ["--timeout", str(REPLY_TIMEOUT_S), "--record", str(full_disk), "--overwrite"]
    result = run_cli("demo", _fast_sim_url(tmp_path), *dive, *link)
    assert result.status == 1, result.err
    assert result.err.endswith(
        f"rovlink demo: recording to {full_disk} stopped: No space left on device\n"
    )
    assert "motors off and locked" in result.out


@pytest.mark.integration
def test_the_monitor_whose_recording_fails_fails_naming_the_file_and_stops_the_robot(
    full_disk: Path, controller: FakeControllerServer
) -> None:
    # Before: status 0 when the pilot quit, the failure seen only as a passing warning.
    terminal = Terminal(
        "monitor",
        controller.url,
        "--boot-timeout",
        "0",
        "--record",
        str(full_disk),
        "--overwrite",
        stderr_on_terminal=True,
    )
    failure = f"rovlink monitor: recording to {full_disk} stopped: No space left on device\r\n"
    try:
        assert wait_until(lambda: "#qsa!" in _frames(controller), timeout_s=WAIT_S)
        terminal.type("s")  # start: the robot may move now
        assert wait_until(lambda: "#start!" in _frames(controller), timeout_s=WAIT_S)
        terminal.type("q")
        assert terminal.process.wait(timeout=WAIT_S) == 1
        assert terminal.wait_shown(failure.encode())
        assert terminal.shown.endswith(failure.encode())
    finally:
        terminal.close()
    assert wait_until(lambda: controller.fakes[0].frames()[-1:] == ["#stop!"])
