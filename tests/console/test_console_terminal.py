"""The console on a pseudo-terminal of its own, as an operator runs it."""

from __future__ import annotations

import asyncio
import contextlib
import fcntl
import os
import re
import select
import struct
import termios
import threading
from collections.abc import AsyncIterator, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from prompt_toolkit.application import create_app_session, get_app_or_none
from prompt_toolkit.input import create_input
from prompt_toolkit.output import create_output

from rovlink.console.app import run_console
from tests.piloting.rig import Rig, until
from tests.terminals import WAIT_S, Terminal

pytestmark = pytest.mark.integration

CTRL_D = "\x04"


@contextlib.contextmanager
def _drained(master: int) -> Iterator[bytearray]:
    """What the program writes to the pseudo-terminal of ``master``, read as it comes (a full
    terminal would block it), answering its cursor position requests as a terminal does; the
    master is closed on the way out."""
    shown = bytearray()
    wake_r, wake_w = os.pipe()

    def drain() -> None:
        with contextlib.suppress(OSError):
            while wake_r not in select.select([master, wake_r], [], [])[0]:
                data = os.read(master, 4096)
                shown.extend(data)
                for _ in range(data.count(b"\x1b[6n")):
                    os.write(master, b"\x1b[1;1R")  # (any row: the prompt has rows to spare)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    try:
        yield shown
    finally:
        os.write(wake_w, b"x")
        reader.join(WAIT_S)
        for descriptor in (master, wake_r, wake_w):
            os.close(descriptor)


@dataclass
class _ConsoleTerminal:
    """The console running in this process on a pseudo-terminal: type into it, read its screen."""

    master: int
    shown: bytearray
    task: asyncio.Task[None]

    def type(self, text: str) -> None:
        os.write(self.master, text.encode())

    def text(self) -> str:
        """What it wrote, its control sequences left out."""
        return _CONTROL_SEQUENCE.sub("", self.shown.decode(errors="replace"))

    async def wait_shown(self, pattern: str) -> None:
        await until(lambda: re.search(pattern, self.text()) is not None)

    async def finish(self) -> None:
        await asyncio.wait_for(self.task, WAIT_S)


_CONTROL_SEQUENCE = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


@contextlib.asynccontextmanager
async def _console_on_a_terminal(
    tmp_path: Path, columns: int = 80, rows: int = 24
) -> AsyncIterator[_ConsoleTerminal]:
    """``run_console`` on the simulator, its keys and screen a pseudo-terminal of this size."""
    master, slave = os.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", rows, columns, 0, 0))
    try:
        with (
            open(slave, closefd=False) as keys,
            open(slave, "w", closefd=False) as screen,
            _drained(master) as shown,
            create_app_session(input=create_input(keys), output=create_output(screen)),
        ):
            rig = Rig.simulated()
            task = asyncio.create_task(run_console(rig.connect, history_path=tmp_path / "history"))
            terminal = _ConsoleTerminal(master, shown, task)
            try:
                await terminal.wait_shown("connected to ")
                yield terminal
            finally:
                if not task.done():
                    task.cancel()
                    await asyncio.gather(task, return_exceptions=True)
    finally:
        os.close(slave)


def test_on_a_dumb_terminal_a_refused_line_says_why_and_the_next_line_runs(
    tmp_path: Path,
) -> None:
    # TERM=dumb (an editor's shell buffer) has no room under the line for the message: before,
    # a refused line said nothing and stayed, and the next line was typed onto its end.
    terminal = Terminal("console", "sim://", "--history", str(tmp_path / "history"), term="dumb")
    try:
        assert terminal.wait_shown(b"connected to ")
        terminal.type("th 400 1\r")
        assert terminal.wait_shown("th: direction_deg must be in 0–360, got 400".encode())
        terminal.type("qd\r")
        assert terminal.wait_shown("qd → 0 cm".encode())
        terminal.type(CTRL_D)
        assert terminal.process.wait(timeout=WAIT_S) == 0
    finally:
        terminal.close()


def test_ctrl_z_between_prompts_does_not_suspend_the_console(tmp_path: Path) -> None:
    # Between one prompt and the next, prompt_toolkit puts the terminal back in its cooked mode
    # for a moment: a Ctrl-Z typed then was the terminal's, and suspended the console (as a job
    # of a shell with job control) with the robot moving. That moment is made to last here: the
    # signal keys are turned on as the cooked mode has them, and Ctrl-Z typed.
    terminal = Terminal(
        "console",
        "sim://",
        "--history",
        str(tmp_path / "history"),
        job_control=True,
        env={"PROMPT_TOOLKIT_NO_CPR": "1"},  # (this terminal answers no cursor position request)
    )
    try:
        assert terminal.wait_shown(b"connected to ")
        terminal.type("start\rth 90 40\r")
        assert terminal.wait_shown(b"#th.90.40!")
        terminal.signal_keys_on()
        terminal.type("\x1a")  # (sends SIGTSTP to the console's process group)
        assert terminal.wait_until(lambda shown: b"does not suspend" in shown or b"job" in shown)
        assert b"[job ended" not in terminal.shown
        terminal.type("qd\r")  # still at the helm
        assert terminal.wait_shown("qd → ".encode())
        terminal.type(CTRL_D)
        assert terminal.process.wait(timeout=WAIT_S) == 0
    finally:
        terminal.close()


async def test_replies_are_printed_with_the_terminal_left_in_raw_mode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, each line printed above the prompt put the terminal back in its cooked mode for a
    # moment (prompt_toolkit's run_in_terminal): a Ctrl-Z typed then suspended the console with
    # the robot moving, Ctrl-C and Ctrl-\ were signals, a Ctrl-D was lost.
    signal_keys_while_prompting: list[int] = []
    set_attributes = termios.tcsetattr

    def watched(fd: int, when: int, attributes: list[Any]) -> None:
        app = get_app_or_none()
        if attributes[3] & termios.ISIG and app is not None and app.is_running:
            signal_keys_while_prompting.append(fd)
        set_attributes(fd, when, attributes)

    monkeypatch.setattr(termios, "tcsetattr", watched)
    async with _console_on_a_terminal(tmp_path) as terminal:
        terminal.type("debug1\rstart\rqd\r")
        await terminal.wait_shown("qd → 0 cm")
        terminal.type(CTRL_D)
        await terminal.finish()
    assert "⋯ debug: motors unlocked" in terminal.text()
    assert signal_keys_while_prompting == []


async def test_at_80_columns_the_toolbar_shows_the_link_s_state_in_full(tmp_path: Path) -> None:
    # Before, the toolbar's first line was cut at the terminal's edge: unlocked in direct mode,
    # checksum on, at 80 columns "link ok, reply 3 ms" read "li" (and "link lost, reopening
    # it" read "link lost,").
    async with _console_on_a_terminal(tmp_path, columns=80) as terminal:
        terminal.type("start\rmvdirect 1\rmvs -50\rchecksum on\rqd\r")
        await terminal.wait_shown(r"thrust -50 % │ checksum crc8")
        await terminal.wait_shown(r"link ok, reply \d+ ms")
        terminal.type(CTRL_D)
        await terminal.finish()


async def test_in_a_terminal_8_rows_high_the_line_and_the_toolbar_are_drawn(tmp_path: Path) -> None:
    # Before, the rows kept for the completion menu (8) and the toolbar's made the layout
    # higher than the terminal: prompt_toolkit drew "Window too small..." in their place.
    async with _console_on_a_terminal(tmp_path, columns=80, rows=8) as terminal:
        terminal.type("qd\r")
        await terminal.wait_shown(r"qd → \d+ cm")
        await terminal.wait_shown(r"Ctrl-X: STOP.*\n?.*link ok, reply")
        assert "Window too small" not in terminal.text()
        terminal.type(CTRL_D)
        await terminal.finish()


async def test_at_40_columns_a_refused_line_s_message_is_shown_whole(tmp_path: Path) -> None:
    # Before, the message under the line was cut at the terminal's edge: at 40 columns
    # "th: direction_deg must be in 0–360, got" without the value that was refused.
    async with _console_on_a_terminal(tmp_path, columns=40) as terminal:
        terminal.type("th 400 25\r")
        await terminal.wait_shown(r"got\s*400")
        terminal.type("\x03" + CTRL_D)
        await terminal.finish()


async def test_a_refused_value_thousands_of_digits_long_takes_three_toolbar_rows(
    tmp_path: Path,
) -> None:
    # The message names the value refused, whole: wrapped whole in the toolbar it took every row
    # of the screen; three rows, the last cut with "…".
    async with _console_on_a_terminal(tmp_path, columns=60, rows=30) as terminal:
        terminal.type(f"th {'1' * 400} 5\r")
        await terminal.wait_shown(r"got 1+\s+1+\s+…")
        terminal.type("\x03" + CTRL_D)
        await terminal.finish()
