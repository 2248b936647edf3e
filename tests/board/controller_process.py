"""``rovlink controller`` in a subprocess, as a user (or systemd) runs it."""

from __future__ import annotations

import re
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from tests.rovlink_process import rovlink_command, rovlink_environment, running_rovlink

_PTY = re.compile(r"\bpty ([^\s,;]+)")
_TCP = re.compile(r"\btcp ([^\s,;]+):(\d+)")
_READY_TIMEOUT_S = 30.0


@dataclass(frozen=True)
class ControllerProcess:
    """A running ``rovlink controller`` and where it serves."""

    process: subprocess.Popen[str]
    ready_line: str
    stderr_path: Path
    pty_path: str | None
    tcp_url: str | None

    def stderr(self) -> str:
        return self.stderr_path.read_text(encoding="utf-8", errors="replace")


def controller_command(*arguments: str) -> list[str]:
    """The command line of ``rovlink controller ARGUMENTS`` with this checkout's sources."""
    return rovlink_command("controller", *arguments)


def environment() -> dict[str, str]:
    return rovlink_environment()


@contextmanager
def running_controller(tmp_path: Path, *arguments: str) -> Iterator[ControllerProcess]:
    """Start ``rovlink controller ARGUMENTS``, wait for its ready line, stop it afterwards."""
    stderr_path = tmp_path / "controller.stderr"
    with (
        stderr_path.open("w", encoding="utf-8") as stderr,
        running_rovlink(
            "controller", *arguments, ready_timeout_s=_READY_TIMEOUT_S, stderr=stderr
        ) as (process, line),
    ):
        assert "ready" in line, (
            f"unexpected first line: {line!r}; stderr: {stderr_path.read_text(encoding='utf-8')}"
        )
        pty = _PTY.search(line)
        tcp = _TCP.search(line)
        yield ControllerProcess(
            process,
            line,
            stderr_path,
            pty.group(1) if pty else None,
            f"socket://{tcp.group(1)}:{tcp.group(2)}" if tcp else None,
        )
