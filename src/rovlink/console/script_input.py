"""The console's input when its lines come from a file or a pipe (``rovlink console < dive.txt``).

prompt_toolkit reads keys, not lines: a script's bytes read as keys lost a last line without its
line end (the end of the input came with it still being typed), and a tab (the completion key)
vanished, so ``th<TAB>90<TAB>30`` was refused as ``th9030``. And prompt_toolkit reads its input
through the event loop, which cannot watch a regular file (epoll refuses one). So the script is
read here, a line at a time as it comes (a pipe's lines may come slowly), in a thread (the
console's input is a pipe that holds 64 KB), and each line is handed on as text pasted
(bracketed paste: its characters are text, not keys), then Enter. The thread reads the
descriptor itself: left waiting on a pipe when the console ends, it must hold no lock of
``sys.stdin``'s, which the interpreter takes as it exits (it aborted, "could not acquire lock
... at interpreter shutdown"). A closed standard input (``<&-``) is a script without lines.

Drawn on a terminal, the prompt does not ask the terminal where its cursor is: the answer
would come on the terminal's input, which nothing reads here; the terminal echoed it
(``^[[3;1R``) in the middle of the replies, and left it for the shell to read as typed.
"""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from typing import TextIO

from prompt_toolkit.application import create_app_session
from prompt_toolkit.input import PipeInput, create_pipe_input
from prompt_toolkit.output import create_output
from prompt_toolkit.output.vt100 import Vt100_Output

__all__ = ["script_input", "typed_line"]

_PASTE_START = "\x1b[200~"
_PASTE_END = "\x1b[201~"
_ENTER = "\r"
#: What an escape character in a line becomes (it could end the paste, or start a key).
_ESCAPE_SHOWN = "^["


@contextlib.contextmanager
def script_input(stdin: TextIO | None) -> Iterator[None]:
    """Inside, the console reads the lines of ``stdin`` (a file or a pipe, not a terminal;
    ``None`` when standard input is closed: no lines). A stream without a descriptor (one a
    test gave) changes nothing: the console reads the input its app session has."""
    try:
        descriptor = None if stdin is None else stdin.fileno()
    except (OSError, ValueError):
        yield
        return
    output = create_output()
    if isinstance(output, Vt100_Output):
        output.enable_cpr = False  # (no cursor position request)
    with create_pipe_input() as keys, create_app_session(input=keys, output=output):
        feeder = threading.Thread(target=_feed, args=(descriptor, keys), daemon=True)
        feeder.start()
        yield


def typed_line(line: bytes, *, first: bool = False) -> str:
    """What the console's input is given for one line of a script (its line end with it or
    not): the line as pasted text, then Enter. UTF-8, a byte that is not shown as ``�``; the
    byte-order mark an editor may put before the ``first`` line is left out.

    >>> typed_line(b"th\\t90\\t30\\r\\n")
    '\\x1b[200~th\\t90\\t30\\x1b[201~\\r'
    >>> typed_line(b"\\xef\\xbb\\xbfstart", first=True)
    '\\x1b[200~start\\x1b[201~\\r'
    """
    text = line.decode("utf-8-sig" if first else "utf-8", errors="replace").rstrip("\r\n")
    return f"{_PASTE_START}{text.replace(chr(27), _ESCAPE_SHOWN)}{_PASTE_END}{_ENTER}"


def _feed(descriptor: int | None, keys: PipeInput) -> None:
    """Hand each line of the script to the console's input as it comes, then its end (the end
    of the lines)."""
    with contextlib.suppress(OSError, ValueError):  # (the console left before the end)
        try:
            lines = () if descriptor is None else _lines(descriptor)
            for number, line in enumerate(lines, start=1):
                keys.send_text(typed_line(line, first=number == 1))
        finally:
            keys.close()


def _lines(descriptor: int) -> Iterator[bytes]:
    """The lines read from ``descriptor`` as they come, without their ``\n``; the last one
    even without it."""
    pending = b""
    while chunk := os.read(descriptor, 4096):
        *complete, pending = (pending + chunk).split(b"\n")
        yield from complete
    if pending:
        yield pending
