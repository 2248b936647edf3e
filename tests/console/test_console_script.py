"""``rovlink console URL < lines.txt | program``: a script's lines run, and its output to a file
or a pipe is their replies alone."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

_SRC = str(Path(__file__).resolve().parents[2] / "src")
_SCRIPT = "start\nqd\nstop\n"
_REPLIES = [
    "  → #start!",
    "  → #qd!",
    "  qd → 0 cm                 $qd.0!",
    "  → #stop!",
]


def _console(tmp_path: Path, stdin: int | None, script: str | None = None) -> tuple[str, str]:
    """Run the console on the simulator, its standard input ``stdin`` (``None``: a pipe
    carrying ``script``) and its output a pipe; what it wrote to stdout and stderr."""
    result = subprocess.run(
        [sys.executable, "-m", "rovlink", "console", "sim://", "--history", str(tmp_path / "h")],
        stdin=stdin,
        input=script,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": _SRC},
        timeout=30,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    return result.stdout, result.stderr


def _check(stdout: str, stderr: str) -> None:
    assert stdout.splitlines() == _REPLIES
    assert "\r" not in stdout
    assert stderr == (
        "rovlink console: connected to simulated controller; its lines run in order; Ctrl-C "
        "sends #stop! and ends the console\n"
    )  # (and not prompt_toolkit's "Warning: Input is not a terminal")


def test_a_script_read_from_a_pipe_writes_its_replies_alone_to_a_pipe(tmp_path: Path) -> None:
    # Before, the output was the prompt drawn as plain text: "rovlink>" lines, blank lines, each
    # line echoed after the prompt, "\r\n" line ends.
    _check(*_console(tmp_path, None, _SCRIPT))


def test_a_script_read_from_a_file_runs_and_writes_its_replies_alone_to_a_pipe(
    tmp_path: Path,
) -> None:
    # Before, `rovlink console URL < script.txt` ran none of its lines: prompt_toolkit cannot
    # watch a regular file, and its first prompt read the end of the input.
    script = tmp_path / "script.txt"
    script.write_text(_SCRIPT, encoding="utf-8")
    with script.open("rb") as lines:
        _check(*_console(tmp_path, lines.fileno()))


def _run_script(stdin: int | None, script: str | None = None) -> subprocess.CompletedProcess[str]:
    """The console on the simulator, its standard input ``stdin`` (``None``: a pipe carrying
    ``script``), with no history kept."""
    return subprocess.run(
        [sys.executable, "-m", "rovlink", "console", "sim://", "--history", os.devnull],
        stdin=stdin,
        input=script,
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": _SRC},
        timeout=30,
        check=False,
    )


@pytest.mark.parametrize("source", ["pipe", "file"])
def test_a_script_s_last_line_without_its_line_end_runs(tmp_path: Path, source: str) -> None:
    # Before, the script's bytes were typed as keys, and the end of the input came while its
    # last line was still being typed: that line was dropped, silently, with status 0.
    script = "start\nqd"  # (the #stop! is the console's, on leaving unlocked)
    if source == "pipe":
        result = _run_script(None, script)
    else:
        path = tmp_path / "script.txt"
        path.write_text(script, encoding="utf-8")
        with path.open("rb") as lines:
            result = _run_script(lines.fileno())
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == _REPLIES


def test_a_script_s_tabs_and_byte_order_mark_are_text_not_keys() -> None:
    # Before, a tab (the completion key) vanished ("unknown command 'th9030'"), and the mark an
    # editor puts before a file's first line made it an unknown command.
    result = _run_script(None, "\ufeffstart\nth\t90\t30\nstop\n")
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == ["  → #start!", "  → #th.90.30!", "  → #stop!"]


def test_a_script_s_escape_is_refused_not_read_as_a_key() -> None:
    # Before, "th 90 30" followed by the bytes of the up-arrow key ran as "th 90 30".
    result = _run_script(None, "start\nth 90 30\x1b[A\n")
    assert result.returncode == 1
    assert "→ #th" not in result.stdout
    assert "line 2: th: power_percent must be an integer in 0–100, got '30^[[A'" in result.stderr


def test_a_closed_standard_input_is_a_script_without_lines() -> None:
    # Before, `rovlink console <&-` ended in a traceback (AttributeError on sys.stdin, None).
    command = [sys.executable, "-m", "rovlink", "console", "sim://", "--history", os.devnull]
    result = subprocess.run(
        ["/bin/sh", "-c", 'exec "$@" <&-', "sh", *command],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": _SRC},
        timeout=30,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert result.stdout.splitlines() == ["  → #stop!"]  # (the lock was unknown)


def test_a_console_that_leaves_before_its_pipe_ends_exits_cleanly() -> None:
    # The thread that reads the script's lines is still waiting on the pipe as the console
    # leaves after "quit". Reading through sys.stdin, it held a lock of it that the interpreter
    # takes on its way out: it aborted (status 134, "Fatal Python error: _enter_buffered_busy").
    process = subprocess.Popen(
        [sys.executable, "-m", "rovlink", "console", "sim://", "--history", os.devnull],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": _SRC},
    )
    assert process.stdin is not None
    try:
        process.stdin.write(b"start\nquit\n")
        process.stdin.flush()  # (and kept open: the writer has more to say)
        assert process.wait(timeout=30) == 0
        assert process.stderr is not None
        stderr = process.stderr.read()
        assert b"Fatal Python error" not in stderr, stderr
    finally:
        process.stdin.close()
        if process.poll() is None:
            process.kill()
        process.wait(timeout=30)


def test_a_script_drawn_on_a_terminal_asks_it_nothing(tmp_path: Path) -> None:
    # Before, the prompt drawn on the terminal asked where its cursor was (ESC [6n): the
    # answer came on the terminal's input, which nothing read under a script, and the terminal
    # echoed it (^[[3;1R) among the replies and left it for the shell to read as typed.
    script = tmp_path / "script.txt"
    script.write_text(_SCRIPT, encoding="utf-8")
    controller, terminal = os.openpty()
    with script.open("rb") as lines:
        process = subprocess.Popen(
            [sys.executable, "-m", "rovlink", "console", "sim://", "--history", os.devnull],
            stdin=lines,
            stdout=terminal,
            stderr=terminal,
            env={**os.environ, "PYTHONPATH": _SRC, "TERM": "xterm-256color"},
        )
    os.close(terminal)
    shown = bytearray()
    try:
        with contextlib.suppress(OSError):  # (EIO once the console has closed its terminal)
            while data := os.read(controller, 4096):
                shown += data
        assert process.wait(timeout=30) == 0, shown
    finally:
        if process.poll() is None:
            process.kill()
        os.close(controller)
    assert b"qd \xe2\x86\x92 0 cm" in shown  # (the replies were drawn)
    assert b"\x1b[6n" not in shown
