"""``rovlink sim`` in a subprocess for the driver benchmarks: start it, read where it listens."""

from __future__ import annotations

import re
import selectors
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

_PTY = re.compile(r"\bpty ([^\s,]+)")
_TCP = re.compile(r"\btcp ([^\s,]+):(\d+)")


@dataclass(frozen=True)
class Sim:
    """Where a running ``rovlink sim`` listens."""

    pty_path: str
    tcp_host: str
    tcp_port: int

    @property
    def tcp_url(self) -> str:
        """The driver URL of its TCP port."""
        return f"socket://{self.tcp_host}:{self.tcp_port}"


@contextmanager
def running_sim(*options: str) -> Iterator[Sim]:
    """``rovlink sim --pty --tcp 0 OPTIONS`` until the block ends."""
    process = subprocess.Popen(
        [sys.executable, "-c", "from rovlink.cli import main; main()", "sim", "--pty",
         "--tcp", "0", *options],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
    )
    try:
        assert process.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(process.stdout, selectors.EVENT_READ)
            if not selector.select(30):
                raise RuntimeError("rovlink sim did not start")
        line = process.stdout.readline()
        pty, tcp = _PTY.search(line), _TCP.search(line)
        if not (pty and tcp):
            raise RuntimeError(f"unexpected ready line from rovlink sim: {line!r}")
        yield Sim(pty.group(1), tcp.group(1), int(tcp.group(2)))
    finally:
        process.terminate()
        try:
            process.wait(5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
