"""Whose terminal a pseudo-terminal is: a port that is some session's controlling terminal is a
person's terminal window (or ``ssh`` login), never a controller's.

Pseudo-terminal numbers are reused: once ``rovlink sim --pty`` or ``socat`` ends, its
``/dev/pts/N`` may next be a new terminal window's, and a client reopening that path would write
frames into someone's shell and take their keystrokes for replies. A controller's
pseudo-terminal (the simulator's, socat's) is no process's controlling terminal; a terminal
window's always is (its shell's).

Linux only, through ``/proc/PID/stat``'s ``tty_nr`` (the device number of each process's
controlling terminal) against the device's ``st_rdev``: the kernel offers no way to ask a
terminal for its session but from inside that session (``TIOCGSID``), and the scan reads one
small file per process, a few milliseconds, on an open or a reopen only. Elsewhere, or where
``/proc`` cannot be read, nothing is found and the port opens as before.

>>> terminal_owner("/dev/no-such-port") is None
True
"""

from __future__ import annotations

import os
import stat
from typing import NamedTuple

__all__ = ["PSEUDO_TERMINAL_MAJORS", "TerminalOwner", "terminal_owner"]

#: Device numbers of Unix98 pseudo-terminals' terminal sides (Linux's devices.txt).
PSEUDO_TERMINAL_MAJORS = range(136, 144)


class TerminalOwner(NamedTuple):
    """A process whose controlling terminal a port is: its session's leader where it can be
    seen (the shell), else the first such process found."""

    pid: int
    name: str


def terminal_owner(path: str) -> TerminalOwner | None:
    """The process whose controlling terminal the pseudo-terminal ``path`` is, or None (not a
    pseudo-terminal, no process's terminal, or not Linux).

    Example::

        owner = terminal_owner("/dev/pts/3")
        if owner is not None:
            print(f"/dev/pts/3 is the terminal of {owner.name} (pid {owner.pid})")
    """
    try:
        status = os.stat(path)
    except OSError:
        return None
    if not stat.S_ISCHR(status.st_mode) or os.major(status.st_rdev) not in PSEUDO_TERMINAL_MAJORS:
        return None
    device = (os.major(status.st_rdev), os.minor(status.st_rdev))
    try:
        pids = [entry for entry in os.listdir("/proc") if entry.isdigit()]
    except OSError:
        return None
    found: TerminalOwner | None = None
    for pid in pids:
        fields = _stat_fields(pid)
        if fields is None:
            continue
        name, session, tty_nr = fields
        if tty_nr == 0 or (os.major(tty_nr), os.minor(tty_nr)) != device:
            continue
        owner = TerminalOwner(int(pid), name)
        if owner.pid == session:
            return owner  # the session's leader: its shell
        found = found or owner
    return found


def _stat_fields(pid: str) -> tuple[str, int, int] | None:
    """Process ``pid``'s name, session id and ``tty_nr`` from ``/proc/PID/stat``, or None if it
    ended meanwhile or cannot be read."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as file:
            text = file.read().decode("utf-8", "replace")
    except OSError:
        return None
    # "PID (NAME) STATE PPID PGRP SESSION TTY_NR ...": NAME may hold spaces and parentheses.
    opening, closing = text.find("("), text.rfind(")")
    rest = text[closing + 1 :].split()
    if opening < 0 or len(rest) < 5:
        return None
    try:
        return text[opening + 1 : closing], int(rest[3]), int(rest[4])
    except ValueError:
        return None
