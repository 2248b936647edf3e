"""Log every frame and event of a connection as JSON lines, through the client's one hook.

Shows ``on_event``: the client calls it with every event of the connection, in order — the
bytes written (``out``) and read (``in``) exactly as on the wire, every reply with the query it
answered, and what the session decided itself (``local``: a failed query, a suspected reset, an
expired motion). :class:`FrameLog` writes each as one JSON object per line with its time, so a
team can add it to any program (``on_event=FrameLog(file)``) and read the log with ``jq`` or
pandas. The session it logs here is short: read the sensors, unlock, move ahead for a while
(renewing the command), lock; Ctrl-C, SIGTERM (``kill``, ``systemctl stop``), SIGHUP (the
terminal or the SSH session closed) and SIGQUIT (Ctrl-\\) lock it too.

Run it::

    python examples/frame_logger.py                                 # the simulator, to stdout
    python examples/frame_logger.py /dev/ttyUSB0 --output dive.jsonl
    python examples/frame_logger.py --output - | jq -c 'select(.direction == "out")'

A line looks like::

    {"t_s": 0.0213, "utc": "2026-01-05T10:31:07.123456+00:00", "direction": "out",
     "event": "BytesSent", "data": "#qsa!", "command": "#qsa!", "by_session": false,
     "retry": false}

``t_s`` is the session's clock, in seconds since the first event (for intervals); ``utc`` is the
wall clock when the hook ran (to line the log up with other records). What answered no query
(``"event": "Unsolicited"``) is under ``unsolicited``: ``{"type": "Text", "text": …}`` for
debug text or noise, ``{"type": "BadFrame", "reason": …, "raw": …, "detail": …}`` for a dropped
frame, ``{"type": "Frame", …}`` for a stray one.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import enum
import json
import logging
import signal
import sys
import time
from collections.abc import Sequence
from datetime import datetime, timezone
from types import FrameType
from typing import IO

import rovlink
from rovlink.client import ClientError, ClientEvent, ConnectionLostError, parse_url
from rovlink.protocol import BadFrame, Command, Frame, Response, Text

log = logging.getLogger("frame_logger")

#: Seconds between two ``move`` commands while moving: well within ``motion_timeout`` (2 s).
RENEW_INTERVAL_S = 0.5

#: An event's field written under another name: ``Unsolicited.event`` (what answered no query)
#: would overwrite the line's own ``event``.
FIELD_KEYS = {"event": "unsolicited"}


def jsonable(value: object) -> object:
    """An event's field as JSON: bytes as text (non-ASCII escaped), frames as they are written."""
    if isinstance(value, bytes):
        return value.decode("ascii", "backslashreplace")
    if isinstance(value, (Command, Response)):
        return str(value)  # the frame without checksum: '#th.0.30!', '$qd.42!'
    if isinstance(value, enum.Enum):
        return value.name.lower()
    if isinstance(value, (tuple, list)):
        return [jsonable(item) for item in value]
    if isinstance(value, (Text, BadFrame, Frame)):  # debug text, line noise, a dropped frame
        fields = {name: jsonable(getattr(value, name)) for name in type(value).__match_args__}
        return {"type": type(value).__name__, **fields}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return repr(value)


class FrameLog:
    """An ``on_event`` hook that writes each event as a line of JSON to ``stream``.

    The client calls it from one thread at a time, in order, so it needs no lock; it flushes
    each line so that a crash loses nothing already seen. A stream that fails (a full disk, a
    reader that went away) stops the log, not the program: the error is logged once and kept
    in :attr:`error`.
    """

    def __init__(self, stream: IO[str]) -> None:
        self.stream = stream
        self.lines = 0
        #: Why the log stopped early, if it did.
        self.error: OSError | None = None
        self._first_at_s: float | None = None

    def __call__(self, event: ClientEvent) -> None:
        if self.error is not None:
            return
        if self._first_at_s is None:
            self._first_at_s = event.at_s
        record: dict[str, object] = {
            "t_s": round(event.at_s - self._first_at_s, 6),
            "utc": datetime.now(timezone.utc).isoformat(),
            "direction": event.direction,
            "event": type(event).__name__,
        }
        for field in dataclasses.fields(event):
            if field.name != "at_s":
                record[FIELD_KEYS.get(field.name, field.name)] = jsonable(
                    getattr(event, field.name)
                )
        try:
            self.stream.write(json.dumps(record, ensure_ascii=False) + "\n")
            self.stream.flush()
        except OSError as error:
            self.error = error
            log.error("the frame log stopped after %d lines: %s", self.lines, error)
        else:
            self.lines += 1


def short_session(url: str, frame_log: FrameLog, move_s: float, *, checksum: bool = False) -> None:
    """Read the sensors, unlock, move ahead for ``move_s`` seconds, lock; every event logged."""
    with rovlink.connect(url, checksum=checksum, on_event=frame_log) as rov:
        try:
            reading = rov.sensors()
            log.info("depth %d cm, heading %d°", reading.depth_cm, reading.heading_deg)
            rov.start()
            ends_at = time.monotonic() + move_s
            while time.monotonic() < ends_at:
                rov.move(0, 20)
                time.sleep(min(RENEW_INTERVAL_S, max(ends_at - time.monotonic(), 0.0)))
            rov.move(0, 0)
        finally:
            try:
                rov.stop()
            except ConnectionLostError as error:
                # Nothing can be sent; the controller's link-loss failsafe stops the robot.
                log.error("could not send #stop!: %s", error)


def open_output(path: str) -> IO[str]:
    """The file to write the log to; ``-`` is standard output (left open when closed)."""
    if path == "-":
        return open(sys.stdout.fileno(), "w", encoding="utf-8", closefd=False)
    return open(path, "w", encoding="utf-8")


def take_termination_as_ctrl_c() -> None:
    """Have SIGTERM (``kill``, ``systemctl stop``), SIGHUP (the terminal or the SSH session
    closed) and SIGQUIT (Ctrl-\\) end the program as Ctrl-C does: through the ``finally`` that
    sends ``#stop!``.

    Python's default for each ends the process at once, running no ``finally``: the robot would
    keep its last command until the controller's link-loss failsafe stopped it. A signal ignored
    on entry (``nohup``) stays ignored.
    """

    def as_ctrl_c(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt(signal.Signals(signum).name)

    for name in ("SIGTERM", "SIGHUP", "SIGQUIT"):  # (Windows has neither of the last two)
        signum = getattr(signal, name, None)
        if signum is not None and signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, as_ctrl_c)


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line: the URL (default ``sim://``), the output and the time moving."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "url", nargs="?", default="sim://", help="the robot's port or URL (default: sim://)"
    )
    parser.add_argument(
        "--output", default="-", metavar="FILE", help="JSON lines file ('-', the default: stdout)"
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=1.0,
        metavar="SECONDS",
        help="time moving ahead at 20 %% (default: 1)",
    )
    parser.add_argument(
        "--checksum",
        action="store_true",
        help="checksum mode (CRC-8): a frame a noisy line damaged is dropped, never acted on",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="show the driver's log")
    args = parser.parse_args(argv)
    try:
        parse_url(args.url)  # as connect checks it: a typo is a usage error, not a traceback
    except ValueError as error:
        parser.error(str(error))
    if not args.duration >= 0:  # (NaN too)
        parser.error(f"--duration must not be negative, got {args.duration:g}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Log the session; exit status 0, or 1 if the link or the log failed, 130 after Ctrl-C,
    SIGTERM, SIGHUP or SIGQUIT."""
    args = parse_arguments(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        stream = open_output(args.output)
    except OSError as error:
        log.error("cannot write the log: %s", error)
        return 1
    frame_log = FrameLog(stream)
    try:
        short_session(args.url, frame_log, args.duration, checksum=args.checksum)
    except (ClientError, TimeoutError, ConnectionError) as error:  # the link, a query
        log.error("session aborted: %s", error)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        # Each line was flushed as it was written: what is left is a line the stream refused,
        # and the log's error said so already.
        with contextlib.suppress(OSError):
            stream.close()
    if frame_log.error is not None:
        return 1
    if args.output != "-":
        print(f"{frame_log.lines} events written to {args.output}", flush=True)
    return 0


if __name__ == "__main__":
    take_termination_as_ctrl_c()
    sys.exit(main())
