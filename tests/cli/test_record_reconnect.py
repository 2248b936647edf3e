"""``rovlink record --tap`` over a controller link that drops and comes back, as real processes:
the simulator killed and started again on the same TCP port, and a pseudo-terminal behind a
stable symlink removed and made again (a USB-serial adapter's dropout and its udev name)."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import socket
import subprocess
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from pathlib import Path

import pytest

from rovlink.recorder import read_entries
from rovlink.recorder.entries import EventEntry, FrameEntry, TelemetryEntry, WireEntry
from rovlink.recorder.sink import RecordingDamagedError
from tests.cli.conftest import RunCli
from tests.client.conftest import wait_until
from tests.client.sim_process import SimProcess, running_sim
from tests.recorder.test_reopening import DroppingController
from tests.rovlink_process import rovlink_command, rovlink_environment

pytestmark = pytest.mark.integration

_TIMEOUT_S = 20.0
_PROGRAM_SIDE = re.compile(r"program's side: (socket://[\d.]+:\d+)")


class _Recorder:
    """``rovlink record`` running, its stderr collected."""

    def __init__(self, *arguments: str) -> None:
        self.process = subprocess.Popen(
            rovlink_command("record", *arguments),
            stderr=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            text=True,
            env=rovlink_environment(),
        )
        self.lines: list[str] = []
        self._changed = threading.Condition()
        self._thread = threading.Thread(target=self._collect, daemon=True)
        self._thread.start()

    def _collect(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            with self._changed:
                self.lines.append(line)
                self._changed.notify_all()

    def wait_for_line(self, pattern: re.Pattern[str]) -> re.Match[str]:
        """The first line of stderr that ``pattern`` finds (fails after a timeout)."""
        found: list[re.Match[str]] = []

        def seen() -> bool:
            found[:] = [m for line in self.lines if (m := pattern.search(line))]
            return bool(found) or self.process.poll() is not None

        with self._changed:
            self._changed.wait_for(seen, _TIMEOUT_S)
        assert found, f"rovlink record said: {''.join(self.lines)}"
        return found[0]

    def stop(self) -> int:
        """SIGTERM it; its status."""
        self.process.send_signal(signal.SIGTERM)
        status = self.process.wait(_TIMEOUT_S)
        self._thread.join(_TIMEOUT_S)
        return status

    def kill(self) -> None:
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait(_TIMEOUT_S)


def _program(url: str) -> socket.socket:
    host, port = url.removeprefix("socket://").rsplit(":", 1)
    return socket.create_connection((host, int(port)), timeout=_TIMEOUT_S)


def _answered(program: socket.socket) -> bool:
    """Whether a ``#qd!`` sent now is answered within half a second."""
    program.settimeout(0.5)
    program.sendall(b"#qd!")
    try:
        return b"$qd." in program.recv(256)
    except TimeoutError:
        return False
    finally:
        program.settimeout(_TIMEOUT_S)


def _answered_within_timeout(program: socket.socket) -> bool:
    return any(_answered(program) for _ in range(int(_TIMEOUT_S / 0.5)))


@contextmanager
def _sim_on_tcp(port: int) -> Iterator[tuple[str, SimProcess]]:
    with running_sim("--tcp", f"127.0.0.1:{port}", "--seed", "1") as sim:
        assert sim.tcp_url is not None
        yield sim.tcp_url, sim


@contextmanager
def _sim_on_pty(link: Path) -> Iterator[tuple[str, SimProcess]]:
    with running_sim("--pty", "--seed", "1") as sim:
        assert sim.pty_path is not None
        link.unlink(missing_ok=True)
        link.symlink_to(sim.pty_path)
        yield str(link), sim


def _recorded_across_a_dropout(
    tmp_path: Path,
    first: Callable[[], AbstractContextManager[tuple[str, SimProcess]]],
    again: Callable[[str], AbstractContextManager[tuple[str, SimProcess]]],
    gone: Callable[[], None],
) -> list[object]:
    """Record through the tap while a program drives, the controller going and coming back
    (``again(url)``); the recording's entries."""
    output = tmp_path / "dive.jsonl"
    with first() as (url, sim):
        recorder = _Recorder(url, "-o", str(output), "--tap", "socket://127.0.0.1:0")
        try:
            program = _program(recorder.wait_for_line(_PROGRAM_SIDE).group(1))
            with program:
                assert _answered_within_timeout(program)
                program.sendall(b"#start!#th.90.50!")
                assert _answered_within_timeout(program)
                sim.process.kill()  # the adapter drops out
                sim.process.wait(_TIMEOUT_S)
                gone()
                recorder.wait_for_line(re.compile(r"reconnecting"))
                assert not _answered(program)  # connected, but nothing answers in the gap
                with again(url):
                    # The same program, never disconnected, is served again.
                    assert _answered_within_timeout(program)
                    recorder.wait_for_line(re.compile(r"reconnected"))
                    assert recorder.stop() == 0, "".join(recorder.lines)
        finally:
            recorder.kill()
    return list(read_entries(str(output)))


def _check(entries: list[object]) -> None:
    links = [
        (e.name, i)
        for i, e in enumerate(entries)
        if isinstance(e, EventEntry) and e.event == "link"
    ]
    # (A port may take the first attempt as its process dies, and close it at once: lost
    # again, and reopened again.)
    assert [name for name, _ in links[:1] + links[-1:]] == ["lost", "reconnected"]
    returned = links[-1][1]
    after = entries[returned + 1 :]
    # The tap's #stop! goes first on the link that came back: the program had set the robot
    # moving (and on each reopened link until the controller is heard on one).
    sent = [e for e in after if isinstance(e, WireEntry) and e.direction == "out"]
    assert sent[0].data == b"#stop!"
    assert sent[0].by_session
    # The recording reads on across the gap: the program's queries answered after it.
    assert any(isinstance(e, FrameEntry) and e.kind == "response" and e.name == "qd" for e in after)
    telemetry = [e for e in entries if isinstance(e, TelemetryEntry)]
    assert telemetry[-1].values["thrust_power_percent"] == 0
    assert telemetry[-1].values["locked"] == 1


def test_the_tap_and_its_program_live_through_the_simulator_restarted_on_the_same_port(
    tmp_path: Path,
) -> None:
    port: list[int] = []

    @contextmanager
    def first() -> Iterator[tuple[str, SimProcess]]:
        with _sim_on_tcp(0) as (url, sim):
            port.append(int(url.rsplit(":", 1)[1]))
            yield url, sim

    _check(
        _recorded_across_a_dropout(tmp_path, first, lambda _: _sim_on_tcp(port[0]), lambda: None)
    )


def test_the_tap_and_its_program_live_through_a_pseudo_terminal_made_again_behind_its_symlink(
    tmp_path: Path,
) -> None:
    link = tmp_path / "ttyROV"
    _check(
        _recorded_across_a_dropout(
            tmp_path,
            lambda: _sim_on_pty(link),
            lambda _: _sim_on_pty(link),
            lambda: os.unlink(link),
        )
    )


def test_a_recorder_without_a_tap_records_on_across_a_dropout_and_sends_nothing(
    run_cli: RunCli, tmp_path: Path
) -> None:
    controller = DroppingController(hello=b"$qd.5!")
    output = tmp_path / "line.jsonl"
    recorder = _Recorder(controller.url, "-o", str(output))
    try:
        recorder.wait_for_line(re.compile(r"listening only"))
        assert wait_until(lambda: len(controller.received) == 1, _TIMEOUT_S)
        controller.drop()
        recorder.wait_for_line(re.compile(r"reconnecting"))
        controller.come_back()
        recorder.wait_for_line(re.compile(r"reconnected"))
        # (What the reopened link said is in the file once a flush, each second, put it there.)
        assert wait_until(lambda: len(_replies(output)) == 2, _TIMEOUT_S)  # one each side
        assert recorder.stop() == 0, "".join(recorder.lines)
    finally:
        recorder.kill()
        controller.close()
    assert [bytes(got) for got in controller.received] == [b"", b""]  # nothing of its own
    entries = list(read_entries(str(output)))
    links = [e.name for e in entries if isinstance(e, EventEntry) and e.event == "link"]
    assert links == ["lost", "reconnected"]
    assert len(_replies(output)) == 2
    # decode shows where the gap is, between the frames of each side.
    decoded = [json.loads(line) for line in run_cli("decode", str(output)).out.splitlines()]
    assert [d.get("state", d.get("name")) for d in decoded] == ["qd", "lost", "reconnected", "qd"]


def _replies(path: Path) -> list[FrameEntry]:
    """The ``qd`` frames recorded in ``path`` so far (a file being written ends early)."""
    replies: list[FrameEntry] = []
    with contextlib.suppress(RecordingDamagedError):
        for e in read_entries(str(path)):
            if isinstance(e, FrameEntry) and e.name == "qd":
                replies.append(e)
    return replies
