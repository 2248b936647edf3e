"""The console end to end: keys through prompt_toolkit's pipe input, the screen it prints, and
the frames that reached the (simulated) controller."""

from __future__ import annotations

import asyncio
import contextlib
import io
import logging
import socket
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from prompt_toolkit.application import create_app_session
from prompt_toolkit.input import PipeInput, create_pipe_input
from prompt_toolkit.output import create_output

import rovlink.aio.client
import rovlink.console.app
from rovlink.aio import AsyncClient
from rovlink.cli import build_parser, main
from rovlink.cli.link_options import connect_async
from rovlink.client.links import Link
from rovlink.client.options import StrayCallback
from rovlink.console.app import Connector, StopUnsentError, run_console
from rovlink.piloting.tracked import STOP_KEPT_NOTICE, STOP_UNSENT_NOTICE
from tests.cli.silent_controller import SilentController as CliSilentController
from tests.client.conftest import NO_REPLY_TIMEOUT_S, REPLY_TIMEOUT_S, client_options
from tests.client.fake_controller import FakeControllerServer
from tests.piloting.rig import RecordingLink, Rig, SilentController, until

CTRL_A, CTRL_K, CTRL_X, CTRL_D, UP = "\x01", "\x0b", "\x18", "\x04", "\x1b[A"
CLEAR_LINE = CTRL_A + CTRL_K


@dataclass
class Terminal:
    """The console running on a pipe: type into it, read what it printed."""

    keys: PipeInput
    screen: io.StringIO
    task: asyncio.Task[None]

    def type(self, text: str) -> None:
        self.keys.send_text(text)

    def shown(self) -> str:
        return self.screen.getvalue()

    async def wait_shown(self, text: str) -> None:
        await until(lambda: text in self.shown())

    async def finish(self) -> None:
        await asyncio.wait_for(self.task, 5)


@contextlib.asynccontextmanager
async def _terminal(
    rig: Rig, history_path: Path | None, connect: Connector | None = None
) -> AsyncIterator[Terminal]:
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        task = asyncio.create_task(run_console(connect or rig.connect, history_path=history_path))
        terminal = Terminal(keys, screen, task)
        await terminal.wait_shown("connected to ")
        try:
            yield terminal
        finally:
            if not task.done():
                task.cancel()
                await asyncio.gather(task, return_exceptions=True)


@dataclass
class _SilentLine:
    """A controller that never answers, and a console's connect to it: a reply timeout far
    beyond any test and no retry, so that a query waits until the test ends it."""

    controller: SilentController
    link: RecordingLink

    async def connect(self, on_stray: StrayCallback) -> AsyncClient:
        options = client_options(timeout_s=30.0, retries=0, on_stray=on_stray)
        return await AsyncClient(self.link, options).open()


@pytest.fixture
def line() -> Iterator[_SilentLine]:
    controller = SilentController()
    yield _SilentLine(controller, controller.link())
    controller.close()


async def test_dive_and_surface_with_replies_debug_errors_and_the_stop_key(tmp_path: Path) -> None:
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("debug1\r")
        await term.wait_shown("→ #debug1!")
        term.type("start\r")
        await term.wait_shown("⋯ debug: motors unlocked")  # the controller's debug line
        term.type("mvd 60\r")
        await term.wait_shown("→ #mvd.60!")
        rig.port.advance(20.0)  # simulated seconds: the depth PID takes it down
        term.type("qd\r")
        await term.wait_shown("qd → ")
        depth_cm = int(term.shown().split("qd → ")[-1].split()[0])
        assert 50 <= depth_cm <= 70
        term.type("mvd 0\r")
        await term.wait_shown("→ #mvd.0!")
        rig.port.advance(30.0)
        term.type("#qd!\r")
        await term.wait_shown("qd → 0 cm")
        assert "$qd.0!" in term.shown()

        sent_before = rig.frames()
        term.type("th 400 25\r")  # refused in place: nothing sent
        await term.wait_shown("th: direction_deg must be in 0–360, got 400")
        assert rig.frames() == sent_before

        term.type(CLEAR_LINE + "th 90 3")  # half typed when the stop key is pressed
        term.type(CTRL_X)
        await term.wait_shown("■ STOP (Ctrl-X)")
        await until(lambda: rig.frames()[-1] == "#stop!")
        term.type("0\r")  # the line was left alone: it goes on to be sent whole
        await term.wait_shown("→ #th.90.30!")
        await term.wait_shown("the controller drops th while motion is locked (as last sent)")

        term.type(CTRL_D)
        await term.finish()
    assert rig.frames() == [
        "#crcoff!",
        "#debug1!",
        "#start!",
        "#mvd.60!",
        "#qd!",
        "#mvd.0!",
        "#qd!",
        "#stop!",
        "#th.90.30!",
    ]  # leaving while locked (as last sent) sends nothing more


async def test_in_checksum_mode_a_frame_typed_with_its_checksum_is_sent(tmp_path: Path) -> None:
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("checksum on\r")
        await term.wait_shown("checksum mode on")
        term.type("#qd8C!\r")  # as copied from a log: before, "unknown command 'qd8C'"
        await term.wait_shown("qd → 0 cm")
        term.type("#qd8D!\r")  # a wrong checksum is refused in place
        await term.wait_shown("missing or wrong crc8 checksum")
        term.type(CLEAR_LINE + "quit\r")
        await term.finish()
    assert rig.frames()[:3] == ["#crcoff!", "#crcon!", "#qd8C!"]


async def test_leak_reply_and_qsa(tmp_path: Path) -> None:
    rig = Rig.simulated(leak_at_s=1.0)
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("q.l\r")
        await term.wait_shown("q.l → no leak")
        rig.port.advance(2.0)
        term.type("qsa\r")
        await term.wait_shown("q.l → LEAK: the sensor fired since the last reset")
        for reply in ("qd → ", "qr → ", "qro → ", "qpi → ", "qhe → ", "$q.l.1!"):
            assert reply in term.shown()
        term.type("slreset\rq.l\r")
        await until(lambda: term.shown().count("q.l → no leak") == 2)
        term.type("quit\r")
        await term.finish()
    assert rig.frames()[-1] == "#stop!"  # lock unknown on leaving: made safe


async def test_help_and_completion_menu_are_shown(tmp_path: Path) -> None:
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("help th\r")
        await term.wait_shown("th <direction_deg 0–360> <power_percent 0–100>")
        term.type("mvp")  # completion while typing: names with their descriptions
        await term.wait_shown("vertical (depth) PID derivative gain")
        term.type(CLEAR_LINE + "th 270 ")
        await term.wait_shown("[<power_percent 0–100>]: horizontal power, %")  # the toolbar
        assert "Ctrl-X: STOP" in term.shown()
        term.type(CLEAR_LINE + CTRL_D)
        await term.finish()
    assert rig.frames() == ["#crcoff!", "#stop!"]


async def test_history_is_kept_between_sessions(tmp_path: Path) -> None:
    history_path = tmp_path / "state" / "console_history"
    first = Rig.simulated()
    async with _terminal(first, history_path) as term:
        term.type("qhe\r")
        await term.wait_shown("qhe → ")
        term.type(CTRL_D)
        await term.finish()
    assert "qhe" in history_path.read_text()
    second = Rig.simulated()
    async with _terminal(second, history_path) as term:
        term.type(UP + "\r")  # the previous session's line
        await term.wait_shown("qhe → ")
        term.type(CTRL_D)
        await term.finish()
    assert second.frames()[1] == "#qhe!"


def test_cli_console_on_sim(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``rovlink console sim://``: the real URL, history in the user's state directory. (Its
    input and output are not terminals: the output is the replies, the notice on stderr.)"""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path))
    links: list[RecordingLink] = []
    open_link = rovlink.aio.client.open_link  # type: ignore[attr-defined]

    def recording_open_link(endpoint: object) -> Link:
        link = RecordingLink(open_link(endpoint))  # type: ignore[arg-type]
        links.append(link)
        return link

    monkeypatch.setattr(rovlink.aio.client, "open_link", recording_open_link)
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("qd\r" + CTRL_D)
        status = main(["console", "sim://?seed=1", "--timeout", str(REPLY_TIMEOUT_S)])
    assert status == 0
    assert "connected to simulated controller" in capsys.readouterr().err
    assert "qd → 0 cm" in screen.getvalue()
    (link,) = links
    frames = link.frames()
    assert (frames[0], frames[-1]) == ("#crcoff!", "#stop!")
    assert "#qd!" in frames
    # The history is kept there (made at the start), but not the lines of a pipe: none typed.
    assert (tmp_path / "rovlink" / "console_history").read_text() == ""


def test_a_script_s_output_to_a_file_keeps_the_console_s_own_remarks_on_stderr(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rovlink console URL < lines.txt | tee dive.log`: before, "leaving: sending #stop!
    # (motors ...)" went into the log among the replies, as did a query's error.
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("start\nqd\n")  # (no stop: leaving sends it)
        keys.close()
        status = main(["console", "sim://?seed=1", "--history", str(tmp_path / "history")])
    assert status == 0
    assert screen.getvalue().splitlines() == [
        "  → #start!",
        "  → #qd!",
        "  qd → 0 cm                 $qd.0!",
        "  → #stop!",
    ]
    # (Among other remarks: "connected …", and on a busy machine the simulator's "behind the
    # wall clock" warning.)
    assert (
        "rovlink console: leaving: sending #stop! (motors unlocked (as last sent))"
        in capsys.readouterr().err.splitlines()
    )


@pytest.mark.integration
def test_lines_read_from_a_file_that_fail_as_they_run_end_the_console_with_status_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rovlink console URL < lines.txt` to a controller that does not answer: before, every
    # query failed and the console exited 0, as if the script had run (`send` exits 1).
    silent = CliSilentController()
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("qd\nqd\n")
        keys.close()
        status = main(
            [
                "console",
                silent.url,
                "--boot-timeout",
                "0",
                "--timeout",
                str(NO_REPLY_TIMEOUT_S),
                "--retries",
                "0",
                "--history",
                str(tmp_path / "history"),
            ]
        )
    assert status == 1
    errors = capsys.readouterr().err.splitlines()
    assert sum("✗ #qd! got no valid reply" in line for line in errors) == 2
    assert errors[-1] == "rovlink console: 2 line(s) failed as they ran (each said above)"
    silent.close()


def test_cli_console_leaving_with_the_stop_unsent_exits_1(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    # The console has said it (its transcript, or stderr): the status tells a script.
    async def link_lost(*_: object, **__: object) -> None:
        raise StopUnsentError(STOP_UNSENT_NOTICE)

    monkeypatch.setattr(rovlink.console.app, "run_console", link_lost)
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.close()
        assert main(["console", "sim://", "--history", str(tmp_path / "history")]) == 1


def test_cli_console_refuses_a_bad_url(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["console", "sim://?nosuch=1"]) == 2
    assert "unknown sim option 'nosuch'" in capsys.readouterr().err


@pytest.mark.integration
def test_cli_console_says_when_nothing_listens(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with socket.socket() as probe:  # a free port, closed again: nothing listens on it
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    status = main(["console", f"socket://127.0.0.1:{port}", "--history", str(tmp_path / "history")])
    assert status == 1
    assert capsys.readouterr().err == (
        f"rovlink console: cannot open socket://127.0.0.1:{port}: Connection refused\n"
    )


async def test_interrupted_console_sends_stop_unless_locked(tmp_path: Path) -> None:
    # Ctrl-C from outside (SIGINT) cancels the console: the robot it unlocked is stopped.
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("start\rth 90 30\r")
        await term.wait_shown("→ #th.90.30!")
        term.task.cancel()
        await asyncio.gather(term.task, return_exceptions=True)
    assert rig.frames()[-1] == "#stop!"


async def test_interrupted_console_sends_nothing_more_when_locked(tmp_path: Path) -> None:
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("stop\r")
        await term.wait_shown("→ #stop!")
        term.task.cancel()
        await asyncio.gather(term.task, return_exceptions=True)
    assert rig.frames() == ["#crcoff!", "#stop!"]


async def test_the_library_s_warnings_are_printed_above_the_prompt(tmp_path: Path) -> None:
    # Written to stderr, a warning (a lost link, a suspected reset) would land in the middle
    # of the line being typed; the console prints it as one of its own lines instead.
    library_logger = logging.getLogger("rovlink")
    handlers_before = list(library_logger.handlers)
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        logging.getLogger("rovlink.client").warning("controller reset suspected\x1b[2J")
        await term.wait_shown("! controller reset suspected\\x1b[2J")
        term.type("quit\r")
        await asyncio.wait_for(term.task, 5.0)
    assert library_logger.handlers == handlers_before
    assert library_logger.propagate


@pytest.mark.parametrize("leave", [CTRL_D, "quit\r"], ids=["ctrl-d", "quit"])
async def test_leaving_stops_at_once_not_behind_a_query_waiting_for_its_reply(
    line: _SilentLine, tmp_path: Path, leave: str
) -> None:
    # Before, Ctrl-D and quit were queued behind the lines typed: with a controller that did
    # not answer, the robot went on at 40 % until every query had waited out its timeout
    # (the lines not sent yet were sent first, then #stop!).
    silent, link, connect = line.controller, line.link, line.connect
    async with _terminal(Rig.simulated(), tmp_path / "history", connect) as term:
        term.type("start\rth 0 40\r")
        await until(lambda: b"#th.0.40!" in silent.received)
        term.type("qd\rqhe\r")  # qd waits for a reply that never comes; qhe is queued
        await until(lambda: b"#qd!" in silent.received)
        term.type(leave)
        await term.wait_shown("leaving: 1 queued line(s) dropped, not sent")
        await until(lambda: b"#stop!" in silent.received)
        assert not term.task.done()  # the #qd! is still waiting: the stop did not wait for it
        silent.host_end.shutdown(socket.SHUT_RDWR)  # (the query fails with the link: it ends)
        await term.finish()
    assert link.frames() == ["#crcoff!", "#start!", "#th.0.40!", "#qd!", "#stop!"]


async def test_pasted_lines_run_one_after_another(tmp_path: Path) -> None:
    # A terminal pastes between bracketed-paste marks; before, the lines were one line, refused
    # ("start takes 0 value(s), got 4") and left in the prompt, where Ctrl-K cleared one line.
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("\x1b[200~start\nth 0 40\nqd\n\x1b[201~\r")
        await term.wait_shown("qd → 0 cm")
        term.type("\x1b[200~stop\nmvs 500\x1b[201~\r")  # all refused: not even the stop
        await term.wait_shown("line 2: mvs: thrust_percent must be in -100…+100, got 500")
        term.type("\x03")  # (the Ctrl-C key drops the refused text)
        term.type("\x1b[200~stop\nquit\nstart\x1b[201~\r")  # lines after quit are not run
        await term.finish()
    assert rig.frames() == ["#crcoff!", "#start!", "#th.0.40!", "#qd!", "#stop!"]


async def test_leaving_does_not_wait_out_the_reply_timeout_of_a_query_on_the_wire(
    line: _SilentLine,
    tmp_path: Path,
) -> None:
    # Before, quit sent #stop! at once, then waited for the #qd! on the wire for the whole
    # reply timeout (--timeout, up to an hour), and again while closing, before it ended.
    silent, link, connect = line.controller, line.link, line.connect
    async with _terminal(Rig.simulated(), tmp_path / "history", connect) as term:
        term.type("start\rqd\r")
        await until(lambda: b"#qd!" in silent.received)
        term.type("quit\r")
        await term.finish()
    assert link.frames() == ["#crcoff!", "#start!", "#qd!", "#stop!"]


async def test_ctrl_c_abandons_a_query_waiting_for_its_reply_and_the_lines_queued(
    line: _SilentLine,
    tmp_path: Path,
) -> None:
    # Before, the Ctrl-C key only dropped the line being typed: a query waiting for a reply
    # that never came held every later line for the whole reply timeout (--timeout, up to an
    # hour), with no way to get the console back but to leave it.
    silent, link, connect = line.controller, line.link, line.connect
    async with _terminal(Rig.simulated(), tmp_path / "history", connect) as term:
        term.type("qd\rstart\r")
        await until(lambda: b"#qd!" in silent.received)
        term.type("\x03")
        await term.wait_shown("^C: #qd! abandoned; 1 queued line(s) dropped, not sent")
        term.type("mvd 10\r")  # runs at once: nothing waits for the #qd! any more
        await until(lambda: b"#mvd.10!" in silent.received)
        term.type("\x03")  # nothing running: it only drops the line, as before
        term.type(CTRL_D)
        await term.finish()
    assert link.frames() == ["#crcoff!", "#qd!", "#mvd.10!", "#stop!"]


@pytest.mark.integration
def test_lines_read_from_a_file_all_run_in_order_before_leaving(tmp_path: Path) -> None:
    # `rovlink console URL < lines.txt`: the end of the file is no Ctrl-D key. Leaving at once
    # there dropped the lines still queued behind a query waiting for its reply.
    silent = CliSilentController()
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("qd\rstart\rth 0 30\r" + CTRL_D)  # (pytest's stdin is no terminal)
        status = main(
            [
                "console",
                silent.url,
                "--boot-timeout",
                "0",
                "--timeout",
                str(NO_REPLY_TIMEOUT_S),
                "--retries",
                "0",
                "--history",
                str(tmp_path / "history"),
            ]
        )
    assert status == 1  # (the qd got no reply: a line that failed, said by the status)
    assert silent.wait_for(b"#stop!")  # (as the far end reads it)
    received = bytes(silent.received)
    assert received.index(b"#qd!") < received.index(b"#start!") < received.index(b"#th.0.30!")
    assert received.rindex(b"#stop!") > received.index(b"#th.0.30!")
    silent.close()


@pytest.mark.integration
async def test_a_lost_link_is_reopened_and_the_state_as_last_sent_forgotten(tmp_path: Path) -> None:
    # Before, an adapter unplugged and plugged back ended the link for good: every line said
    # "connection lost" until the console was left and started again.
    port = FakeControllerServer()
    args = build_parser("console").parse_args(
        ["console", port.url, "--boot-timeout", "0", "--timeout", str(REPLY_TIMEOUT_S)]
    )
    async with _terminal(Rig.simulated(), tmp_path / "history", connect_async(args)) as term:
        term.type("start\rth 0 40\r")
        await until(lambda: bool(port.fakes))  # (the fake's own thread takes the connection)
        await until(lambda: "#th.0.40!" in port.fakes[0].frames())
        port.fakes[0].close()
        await term.wait_shown("! link reopened: the controller may have reset (locked)")
        term.type("qd\r")
        await term.wait_shown("qd → 123 cm")
        term.type("status\r")
        await term.wait_shown(
            "motors:     unknown: after the link was reopened (the controller may have reset)"
        )
        term.type(CTRL_D)
        await term.finish()
    # Leaving: the lock unknown (as the fake reads it: a keep-alive may follow).
    await until(lambda: "#stop!" in port.fakes[1].frames())
    assert port.fakes[1].frames()[0] == "#th.0.0!"  # the driver's zero thrust first
    port.close()


async def test_the_toolbar_hint_is_for_the_line_of_a_paste_the_cursor_is_on(
    tmp_path: Path,
) -> None:
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("\x1b[200~start\nth 270 \x1b[201~")  # pasted, not yet entered
        # (Before, the hint was start's: the words of every line counted.)
        await term.wait_shown("th <direction_deg 0–360> [<power_percent 0–100>]")
        term.type("25\r")
        await until(lambda: "#th.270.25!" in rig.frames())
        term.type(CTRL_D)
        await term.finish()


async def test_ctrl_z_says_the_console_is_not_suspended_and_leaves_the_line_alone(
    tmp_path: Path,
) -> None:
    # Before, Ctrl-Z put a ^Z character in the line: "unknown command '\x1a'" once entered.
    rig = Rig.simulated()
    async with _terminal(rig, tmp_path / "history") as term:
        term.type("q")
        term.type("\x1a")
        await term.wait_shown("Ctrl-Z does not suspend the console")
        term.type("d\r")
        await term.wait_shown("qd → 0 cm")
        term.type(CTRL_D)
        await term.finish()
    assert rig.frames() == ["#crcoff!", "#qd!", "#stop!"]  # (the lock not sent: made safe)


@pytest.mark.integration
def test_a_bad_line_read_from_a_file_ends_the_console_naming_it_and_stops(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # `rovlink console URL < lines.txt` with a typo on line 3: before, the refused line stayed
    # in the prompt, the lines after it were typed into it ("th th 400 mvd 10 1"), and the
    # console left with status 0 as if the script had run.
    silent = CliSilentController()
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("start\nth 0 30\nth 400 1\nmvd 10\n")
        keys.close()  # the end of the file
        status = main(
            [
                "console",
                silent.url,
                "--boot-timeout",
                "0",
                "--history",
                str(tmp_path / "history"),
            ]
        )
    assert status == 1
    assert capsys.readouterr().err.splitlines()[-1] == (
        "rovlink console: line 3: th: direction_deg must be in 0–360, got 400"
        " (the lines after it were not run)"
    )
    assert silent.wait_until(lambda received: received.endswith(b"#stop!"))
    received = bytes(silent.received)
    assert received.index(b"#start!") < received.index(b"#th.0.30!") < received.index(b"#stop!")
    assert b"#mvd" not in received
    assert b"#th.400" not in received
    silent.close()


@pytest.mark.integration
def test_lines_read_from_a_file_show_no_toolbar_nor_a_stop_key_that_cannot_be_pressed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Before, the transcript of `rovlink console URL < lines.txt > log` was the toolbar drawn
    # again and again, and it (and the first line) said Ctrl-X sends #stop!: no key reaches a
    # console whose lines come from a file; Ctrl-C, a signal then, stops the robot.
    silent = CliSilentController()
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("start\nth 0 30\n")
        keys.close()
        status = main(
            ["console", silent.url, "--boot-timeout", "0", "--history", str(tmp_path / "history")]
        )
    assert status == 0
    transcript = screen.getvalue()
    assert "→ #th.0.30!" in transcript
    assert "Ctrl-X" not in transcript
    assert "Tab completes" not in transcript
    notice = capsys.readouterr().err  # (the transcript, to a file, is the replies alone)
    assert "Ctrl-C sends #stop! and ends the console" in notice
    assert "Ctrl-X" not in notice
    silent.close()


@pytest.mark.integration
@pytest.mark.parametrize("leave", ["ctrl-d", "signal"])
async def test_a_stop_while_the_link_is_down_says_it_is_kept_and_leaving_says_it_never_went(
    tmp_path: Path, leave: str
) -> None:
    # Before, Ctrl-X with the link down printed "■ STOP" and nothing else (the #stop! had not
    # gone), and leaving printed "leaving: sending #stop!" for a #stop! that never went.
    port = FakeControllerServer()
    args = build_parser("console").parse_args(
        ["console", port.url, "--boot-timeout", "0", "--timeout", str(REPLY_TIMEOUT_S)]
    )
    async with _terminal(Rig.simulated(), tmp_path / "history", connect_async(args)) as term:
        term.type("start\rth 0 40\r")
        await until(lambda: bool(port.fakes))  # (the fake's own thread takes the connection)
        await until(lambda: "#th.0.40!" in port.fakes[0].frames())
        port.refuse = True  # (unplugged, and not yet plugged back)
        port.fakes[0].close()
        await term.wait_shown("! link lost: ")
        term.type(CTRL_X)
        await term.wait_shown(f"! {STOP_KEPT_NOTICE}")
        if leave == "ctrl-d":
            term.type(CTRL_D)
            # Before, leaving so ended as any quit: `rovlink console` exited 0, and a script
            # could not tell that the robot was left to the controller's failsafe.
            with pytest.raises(StopUnsentError):
                await term.finish()
        else:  # (SIGINT, SIGTERM, SIGHUP: the console is cancelled)
            term.task.cancel()
            await asyncio.gather(term.task, return_exceptions=True)
        assert term.shown().count(STOP_UNSENT_NOTICE) == 1
        assert "leaving: sending #stop!" not in term.shown()
    port.close()


async def test_lines_read_from_a_file_are_kept_out_of_the_typed_history(tmp_path: Path) -> None:
    # Before, every line of `rovlink console < dive.txt` went into the history the pilot's
    # up arrow walks through, hundreds of lines of a script among the lines typed.
    history = tmp_path / "history"
    history.write_text("\n# 2026-01-01 00:00:00\n+qhe\n", encoding="utf-8")
    rig = Rig.simulated()
    screen = io.StringIO()
    with create_pipe_input() as keys, create_app_session(input=keys, output=create_output(screen)):
        keys.send_text("start\rqd\rstop\r")
        keys.close()  # (the end of the file)
        await asyncio.wait_for(
            run_console(rig.connect, history_path=history, from_terminal=False), 5
        )
    assert rig.frames()[-3:] == ["#start!", "#qd!", "#stop!"]
    assert history.read_text(encoding="utf-8") == "\n# 2026-01-01 00:00:00\n+qhe\n"
