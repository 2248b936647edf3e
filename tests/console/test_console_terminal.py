"""The console on a pseudo-terminal of its own, as an operator runs it."""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import termios
import threading
from collections.abc import Iterator
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
    rig = Rig.simulated()
    master, slave = os.openpty()
    with (
        open(slave, closefd=False) as keys,
        open(slave, "w", closefd=False) as screen,
        _drained(master) as shown,
        create_app_session(input=create_input(keys), output=create_output(screen)),
    ):
        console = asyncio.create_task(run_console(rig.connect, history_path=tmp_path / "history"))
        os.write(master, b"debug1\rstart\rqd\r")
        await until(lambda: "qd → 0 cm" in shown.decode(errors="replace"))
        os.write(master, CTRL_D.encode())
        await asyncio.wait_for(console, WAIT_S)
    os.close(slave)
    assert "⋯ debug: motors unlocked" in shown.decode(errors="replace")
    assert signal_keys_while_prompting == []
