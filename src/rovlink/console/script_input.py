"""The console's input when its lines come from a file or a pipe (``rovlink console < dive.txt``).

prompt_toolkit reads its input through the event loop, which cannot watch a regular file (epoll
refuses one): with a file as its standard input the first prompt read the end of the input, and
not one line ran. A file's lines are handed to it through a pipe instead, from a thread (a pipe
holds 64 KB: a longer file would block a writer on the event loop's thread). And the warning
prompt_toolkit prints for an input that is not a terminal is left out: it is meant not to be.
"""

from __future__ import annotations

import contextlib
import io
import os
import stat
import threading
from collections.abc import Iterator
from typing import TextIO

from prompt_toolkit.application import create_app_session, get_app_session
from prompt_toolkit.input import PipeInput, create_pipe_input

__all__ = ["script_input"]


@contextlib.contextmanager
def script_input(stdin: TextIO) -> Iterator[None]:
    """Inside, the console reads the lines of ``stdin`` (a file or a pipe, not a terminal)."""
    if not _is_regular_file(stdin):
        with contextlib.redirect_stderr(io.StringIO()):  # ("Input is not a terminal")
            get_app_session().input  # noqa: B018 - made on first use (unless given already)
        yield
        return
    with create_pipe_input() as keys, create_app_session(input=keys):
        feeder = threading.Thread(target=_feed, args=(stdin, keys), daemon=True)
        feeder.start()
        yield


def _is_regular_file(stream: TextIO) -> bool:
    try:
        return stat.S_ISREG(os.fstat(stream.fileno()).st_mode)
    except (OSError, ValueError):  # (no descriptor: a stream a test gave)
        return False


def _feed(stdin: TextIO, keys: PipeInput) -> None:
    """Hand the file's text to the console's input, then its end (the end of the lines)."""
    with contextlib.suppress(OSError, ValueError):  # (the console left before the end)
        while chunk := stdin.buffer.read(4096):
            keys.send_bytes(chunk)
        keys.close()
