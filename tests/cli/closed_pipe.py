"""A command run with its standard output a pipe whose reader has gone (``| head -0``)."""

from __future__ import annotations

import os
import subprocess
import sys


def run_into_a_closed_pipe(*words: str) -> subprocess.CompletedProcess[str]:
    """``rovlink WORDS…`` with its output a pipe closed before the first write; its status and
    standard error (text)."""
    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        return subprocess.run(
            [sys.executable, "-m", "rovlink", *words],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            check=False,
            timeout=60,
        )
    finally:
        os.close(write_end)
