"""``rovlink sim`` in a subprocess, as a user runs it, for tests over a real PTY and TCP."""

from __future__ import annotations

import os
import re
import selectors
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

_SRC = str(Path(__file__).resolve().parents[2] / "src")
_PTY = re.compile(r"\bpty ([^\s,]+)")
_TCP = re.compile(r"\btcp ([^\s,]+):(\d+)")
_READY_TIMEOUT_S = 20.0


@dataclass(frozen=True)
class SimProcess:
    """A running ``rovlink sim`` and where it listens."""

    process: subprocess.Popen[str]
    pty_path: str | None
    tcp_url: str | None


@contextmanager
def running_sim(*arguments: str) -> Iterator[SimProcess]:
    """Start ``rovlink sim ARGUMENTS``, wait for its ready line, stop it afterwards."""
    environment = dict(os.environ)
    environment["PYTHONPATH"] = _SRC + os.pathsep + environment.get("PYTHONPATH", "")
    process = subprocess.Popen(
        [sys.executable, "-c", "from rovlink.cli import main; main()", "sim", *arguments],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=environment,
    )
    try:
        assert process.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(process.stdout, selectors.EVENT_READ)
            if not selector.select(_READY_TIMEOUT_S):
                raise AssertionError("rovlink sim printed no ready line")
        line = process.stdout.readline()
        assert "ready" in line, f"unexpected first line from rovlink sim: {line!r}"
        pty = _PTY.search(line)
        tcp = _TCP.search(line)
        yield SimProcess(
            process,
            pty.group(1) if pty else None,
            f"socket://{tcp.group(1)}:{tcp.group(2)}" if tcp else None,
        )
    finally:
        if process.poll() is None:
            process.terminate()
        try:
            process.communicate(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
