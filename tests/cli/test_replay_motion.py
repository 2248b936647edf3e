"""``rovlink replay --to`` sends the motion the recording holds, no more and no less: the
replaying driver expires no motion of its own."""

from __future__ import annotations

import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from rovlink.recorder import Entry, FrameEntry, HeaderEntry
from rovlink.recorder.formats import open_sink
from tests.cli.conftest import RunCli
from tests.client.conftest import wait_until
from tests.client.fake_controller import FakeControllerServer

pytestmark = pytest.mark.integration

#: Longer than the driver's default motion timeout (2 s): the gap a program that holds a
#: motion (the monitor, with no motion timeout) leaves between two frames.
_HELD_S = 2.2


@pytest.fixture
def controller() -> Iterator[FakeControllerServer]:
    server = FakeControllerServer()
    yield server
    server.close()


def _write(path: Path, entries: list[Entry]) -> None:
    sink = open_sink(str(path))
    for entry in entries:
        sink.write(entry)
    sink.close()


def test_a_motion_held_longer_than_a_motion_timeout_is_replayed_held(
    run_cli: RunCli, tmp_path: Path, controller: FakeControllerServer
) -> None:
    # Before, the replaying driver zeroed the thrust after 2 s of its own (#th.90.0!), which
    # the recorded controller never got: the replies after it differed for that alone.
    recording = tmp_path / "held.jsonl"
    now_s = time.monotonic()
    _write(
        recording,
        [
            HeaderEntry(now_s, 0, "sim://", False, "crc8", "rovlink monitor", "0"),
            FrameEntry(now_s + 0.01, 0, "out", "command", "start", ()),
            FrameEntry(now_s + 0.02, 0, "out", "command", "th", (90, 40)),
            FrameEntry(now_s + 0.02 + _HELD_S, 0, "out", "command", "qd", ()),
            FrameEntry(now_s + 0.03 + _HELD_S, 0, "in", "response", "qd", (123,), query="qd"),
            FrameEntry(now_s + 0.04 + _HELD_S, 0, "out", "command", "stop", ()),
        ],
    )
    result = run_cli("replay", str(recording), "--to", controller.url)
    assert result.status == 0, result.out + result.err
    assert wait_until(lambda: controller.fakes[0].frames()[-1:] == ["#stop!"])
    frames = controller.fakes[0].frames()
    sent = frames[frames.index("#start!") :]
    assert "#qd!" in sent
    # (but for the queries: the replayed one, and the replaying driver's keep-alives)
    assert [frame for frame in sent if frame != "#qd!"] == ["#start!", "#th.90.40!", "#stop!"]


def test_a_replay_says_before_it_starts_which_commands_move_the_robot(
    run_cli: RunCli, tmp_path: Path, controller: FakeControllerServer
) -> None:
    # It said "replaying 4 commands of … to …", nothing of a robot about to be unlocked and
    # driven by a recording someone else made.
    recording = tmp_path / "moving.jsonl"
    now_s = time.monotonic()
    _write(
        recording,
        [
            HeaderEntry(now_s, 0, "sim://", False, "crc8", "rovlink monitor", "0"),
            FrameEntry(now_s + 0.01, 0, "out", "command", "start", ()),
            FrameEntry(now_s + 0.02, 0, "out", "command", "th", (90, 40)),
            FrameEntry(now_s + 0.03, 0, "out", "command", "th", (0, 0)),
            FrameEntry(now_s + 0.04, 0, "out", "command", "stop", ()),
        ],
    )
    result = run_cli("replay", str(recording), "--to", controller.url)
    assert result.status == 0, result.out + result.err
    assert result.err.splitlines()[0] == (
        f"replaying 4 commands of {recording} to {controller.url}; 3 of them unlock or move the "
        "robot (start, th)"
    )
