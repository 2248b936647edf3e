"""``rovlink COMMAND …`` in a subprocess with this checkout's sources, as a user runs it: the
tests' one way to start a server command and wait for the line it prints when it is ready."""

from __future__ import annotations

import os
import selectors
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

_SRC = str(Path(__file__).resolve().parents[1] / "src")


def rovlink_command(*arguments: str) -> list[str]:
    """The command line of ``rovlink ARGUMENTS`` run from this checkout's sources."""
    return [sys.executable, "-c", "from rovlink.cli import main; main()", *arguments]


def rovlink_environment() -> dict[str, str]:
    """This process's environment with this checkout's sources first on the path."""
    environment = dict(os.environ)
    environment["PYTHONPATH"] = _SRC + os.pathsep + environment.get("PYTHONPATH", "")
    return environment


@contextmanager
def running_rovlink(
    *arguments: str, ready_timeout_s: float, stderr: int | IO[Any] | None = subprocess.DEVNULL
) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """Start ``rovlink ARGUMENTS``; yield the process and its first line of output (read within
    ``ready_timeout_s``); terminate it afterwards (killed if it will not end)."""
    process = subprocess.Popen(
        rovlink_command(*arguments),
        stdout=subprocess.PIPE,
        stderr=stderr,
        text=True,
        env=rovlink_environment(),
    )
    try:
        assert process.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(process.stdout, selectors.EVENT_READ)
            if not selector.select(ready_timeout_s):
                raise AssertionError(f"rovlink {arguments[0]} printed no ready line")
        yield process, process.stdout.readline()
    finally:
        if process.poll() is None:
            process.terminate()
        try:
            process.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
