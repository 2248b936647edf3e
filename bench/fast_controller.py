"""``fast_controller.c`` built and running for the host benchmarks: a controller that is not timed.

The C source is compiled at run time with the system's C compiler (``cc -O2``) into a temporary
directory; nothing built is kept. Without a compiler, :class:`NoCompilerError` says so.
"""

from __future__ import annotations

import os
import re
import selectors
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

SOURCE = Path(__file__).with_name("fast_controller.c")
_READY = re.compile(r"^tcp ([^\s:]+):(\d+)$")
_COMPILERS = ("cc", "gcc", "clang")


class NoCompilerError(RuntimeError):
    """No C compiler on this machine: the fast controller cannot be built."""


@dataclass(frozen=True)
class FastController:
    """Where a running fast controller listens."""

    host: str
    port: int

    @property
    def url(self) -> str:
        """The driver URL of its TCP port."""
        return f"socket://{self.host}:{self.port}"


def compile_controller(folder: Path) -> Path:
    """Build ``fast_controller.c`` into ``folder``; the path of the executable."""
    compiler = os.environ.get("CC") or next(filter(shutil.which, _COMPILERS), None)
    if compiler is None:
        raise NoCompilerError(
            "no C compiler found (tried $CC, cc, gcc, clang): install one (e.g. apt-get install "
            "gcc) to build the fast controller these benchmarks time the host against"
        )
    executable = folder / "fast_controller"
    result = subprocess.run(
        [compiler, "-O2", "-o", str(executable), str(SOURCE)],
        check=False,
        capture_output=True,
        text=True,
    )
    if result.returncode != 0:
        raise NoCompilerError(f"{compiler} could not build {SOURCE.name}:\n{result.stderr}")
    return executable


@contextmanager
def running_fast_controller(cpu: int | None = None) -> Iterator[FastController]:
    """Build the fast controller, run it on a free port of 127.0.0.1 until the block ends
    (on CPU ``cpu`` only, if given)."""
    with tempfile.TemporaryDirectory(prefix="rovlink-bench-") as folder:
        executable = compile_controller(Path(folder))
        process = subprocess.Popen(
            [str(executable), "0"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
        )
        try:
            if cpu is not None:
                os.sched_setaffinity(process.pid, {cpu})
            assert process.stdout is not None
            with selectors.DefaultSelector() as selector:
                selector.register(process.stdout, selectors.EVENT_READ)
                if not selector.select(10):
                    raise RuntimeError("the fast controller did not start")
            line = process.stdout.readline().strip()
            ready = _READY.match(line)
            if ready is None:
                raise RuntimeError(f"unexpected ready line from the fast controller: {line!r}")
            yield FastController(ready.group(1), int(ready.group(2)))
        finally:
            process.terminate()
            process.wait(5)
