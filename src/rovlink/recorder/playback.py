"""Reading a recording back as a person reads it: one line per frame and event, at the
recorded pace if asked.

>>> from rovlink.recorder.entries import FrameEntry
>>> describe(FrameEntry(1.25, 0, "in", "response", "qd", (95,), query="qd", round_trip_ms=2.5))
'in   $qd.95!  (answers qd, 2.5 ms)'
>>> describe(HeaderEntry(1.0, 1_795_806_432_000_000_000, "sim://", False, "crc8", "demo", "1"))
'--   demo 1 on sim:// (no checksum), started 2026-11-27 19:07:12 UTC'
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator

from rovlink.protocol import Command, Response, encode
from rovlink.recorder.entries import (
    Entry,
    EventEntry,
    FrameEntry,
    HeaderEntry,
    TelemetryEntry,
    WireEntry,
    utc_text,
)

__all__ = ["describe", "paced", "session_lines", "wait_until"]


def _frame_text(entry: FrameEntry) -> str:
    message = (
        Command(entry.name, entry.values)
        if entry.kind == "command"
        else Response(entry.name, entry.values)
    )
    return encode(message).decode("ascii")


#: The program whose recordings are a tap's: the frames it writes itself (its ``#stop!`` when a
#: program leaves) are the tap's, not a driver's.
_TAP_PROGRAM = "rovlink record"


def describe(entry: Entry, *, wire: bool = False, writer: str = "the driver") -> str | None:
    """The line of one entry (``None``: not shown; raw bytes only with ``wire``); ``writer``
    wrote the frames the session wrote itself (``by_session``).

    >>> stop = FrameEntry(2.0, 0, "out", "command", "stop", (), by_session=True)
    >>> describe(stop, writer="the tap")
    'out  #stop!  (by the tap)'
    """
    if isinstance(entry, FrameEntry):
        text = f"{entry.direction:<4} {_frame_text(entry)}"
        notes = []
        if entry.by_session:
            notes.append(f"by {writer}")
        if entry.retry:
            notes.append("retry by the driver")
        if entry.query is not None:
            answer = f"answers {entry.query}"
            if entry.round_trip_ms is not None:
                answer += f", {entry.round_trip_ms:g} ms"
            notes.append(answer)
        elif entry.direction == "in":
            notes.append("answers no query")
        if entry.late:
            notes.append("late: discarded")
        return f"{text}  ({', '.join(notes)})" if notes else text
    if isinstance(entry, EventEntry):
        parts = [entry.event.replace("_", " ")]
        if entry.name:
            parts.append(entry.name)
        line = "!!   " + " ".join(parts)
        return f"{line}: {entry.detail}" if entry.detail else line
    if isinstance(entry, WireEntry):
        if not wire:
            return None
        marker = ">>" if entry.direction == "out" else "<<"
        return f"{marker}   {entry.data!r}"
    if isinstance(entry, HeaderEntry):
        mode = f"checksum {entry.algorithm}" if entry.checksum else "no checksum"
        line = f"--   {entry.program} {entry.version} on {entry.url or '?'} ({mode})"
        # (The times after it count from it: without the wall clock, nobody could tell when.)
        started = utc_text(entry.wall_ns)
        return f"{line}, started {started}" if started else line
    if isinstance(entry, TelemetryEntry):
        return None
    return None


def paced(
    entries: Iterable[Entry],
    speed: float,
    *,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[Entry]:
    """``entries`` at their recorded pace divided by ``speed`` (a raw capture has no times and
    passes at once)."""
    first_s: float | None = None
    started_s = clock()
    for entry in entries:
        if entry.t_s > 0 and not isinstance(entry, HeaderEntry):
            if first_s is None:
                first_s = entry.t_s
            wait_until(started_s + (entry.t_s - first_s) / speed, sleep=sleep, clock=clock)
        yield entry


#: The longest single sleep: :func:`time.sleep` refuses more than its clock can count (about
#: 292 years), which a damaged time in a recording can ask for.
_LONGEST_SLEEP_S = 3600.0


def wait_until(
    due_s: float,
    *,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> None:
    """Sleep until ``clock()`` reaches ``due_s``, however far off it is."""
    while (delay_s := due_s - clock()) > 0:
        sleep(min(delay_s, _LONGEST_SLEEP_S))


def session_lines(entries: Iterable[Entry], *, wire: bool = False) -> Iterator[str]:
    """Each shown entry as ``"  12.345 s  <line>"`` from the first entry's time."""
    first_s: float | None = None
    writer = "the driver"
    for entry in entries:
        if isinstance(entry, HeaderEntry):
            # (A tap's #stop! was listed "by the driver" in a session no driver took part in.)
            writer = "the tap" if entry.program == _TAP_PROGRAM else "the driver"
        line = describe(entry, wire=wire, writer=writer)
        if line is None:
            continue
        if first_s is None and entry.t_s > 0:
            first_s = entry.t_s
        offset_s = entry.t_s - first_s if first_s is not None and entry.t_s > 0 else 0.0
        yield f"{offset_s:9.3f} s  {line}"
