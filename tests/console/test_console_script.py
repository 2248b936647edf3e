"""``rovlink console URL < lines.txt | program``: a script's lines run, and its output to a file
or a pipe is their replies alone."""

from __future__ import annotations

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
