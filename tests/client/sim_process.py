"""``rovlink sim`` in a subprocess, as a user runs it, for tests over a real PTY and TCP."""

from __future__ import annotations

import re
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from tests.rovlink_process import running_rovlink

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
    with running_rovlink("sim", *arguments, ready_timeout_s=_READY_TIMEOUT_S) as (process, line):
        assert "ready" in line, f"unexpected first line from rovlink sim: {line!r}"
        pty = _PTY.search(line)
        tcp = _TCP.search(line)
        yield SimProcess(
            process,
            pty.group(1) if pty else None,
            f"socket://{tcp.group(1)}:{tcp.group(2)}" if tcp else None,
        )
