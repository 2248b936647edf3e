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


@dataclass(frozen=True)
class Sim:
    """Where a running ``rovlink sim`` listens."""

    pty_path: str


@contextmanager
def running_sim(*options: str) -> Iterator[Sim]:
    """``rovlink sim OPTIONS`` (a pseudo-terminal, its default) until the block ends.

    The pseudo-terminal only: a simulator serving a PTY and TCP at once is not what a robot's
    program meets, and the host round trip is timed against ``fast_controller.c`` instead.
    """
    process = subprocess.Popen(
        [sys.executable, "-c", "from rovlink.cli import main; main()", "sim", *options],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert process.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(process.stdout, selectors.EVENT_READ)
            if not selector.select(30):
                raise RuntimeError("rovlink sim did not start")
        line = process.stdout.readline()
        pty = _PTY.search(line)
        if pty is None:
            raise RuntimeError(f"unexpected ready line from rovlink sim: {line!r}")
        yield Sim(pty.group(1))
    finally:
        process.terminate()
        try:
            process.wait(5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
