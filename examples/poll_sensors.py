"""Poll every sensor at a fixed rate and print one line per reading, until Ctrl-C.

Shows the blocking client (``rovlink.connect``) in the simplest loop a top-level program has:
``sensors()`` sends one ``#qsa!`` and returns depth, pressure, leak, roll, pitch and heading at
once; the loop keeps its rate without drifting (a slow reading delays the next one, never all
the rest); a reading that times out is reported and the loop goes on; a lost link ends it with
a message; Ctrl-C ends it cleanly with a summary. It never unlocks the motors, so it sends no
``#stop!``: it can watch a robot that stays locked.

Run it::

    python examples/poll_sensors.py                          # the simulator (sim://)
    python examples/poll_sensors.py /dev/ttyUSB0 --rate 5    # a robot on a serial port
    python examples/poll_sensors.py socket://192.168.2.2:5760 --duration 10
    python examples/poll_sensors.py -v                        # the driver's log lines too
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass

import rovlink
from rovlink.client import (
    Client,
    ConnectError,
    ConnectionLostError,
    QueryTimeoutError,
    Sensors,
    parse_url,
)

log = logging.getLogger("poll_sensors")


def reading_line(elapsed_s: float, reading: Sensors) -> str:
    """One reading as a line of text, fixed-width so that the columns line up."""
    return (
        f"{elapsed_s:7.2f} s  depth {reading.depth_cm:5d} cm  "
        f"roll {reading.roll_deg:+4d}°  pitch {reading.pitch_deg:+4d}°  "
        f"heading {reading.heading_deg:3d}°  leak {'YES' if reading.leak_detected else 'no'}"
    )


@dataclass
class PollCounts:
    """How the polling went: readings printed, readings that timed out."""

    readings: int = 0
    missed: int = 0


def poll(rov: Client, rate_hz: float, duration_s: float | None, counts: PollCounts) -> None:
    """Read the sensors ``rate_hz`` times a second for ``duration_s`` (None: until Ctrl-C).

    ``counts`` is updated as it goes, so it is right however the loop ends. The schedule is absolute
    (``next_at += period``): a late reading shortens the next wait instead of shifting every
    later reading, and a loop that fell more than a period behind skips ahead rather than
    firing a burst of queries to catch up.
    """
    period_s = 1.0 / rate_hz
    started_at = time.monotonic()
    next_at = started_at
    while duration_s is None or time.monotonic() - started_at < duration_s:
        try:
            reading = rov.sensors()
        except QueryTimeoutError as error:
            counts.missed += 1
            log.warning("no reading: %s", error)
        else:
            counts.readings += 1
            print(reading_line(time.monotonic() - started_at, reading), flush=True)
            if reading.leak_detected:
                log.warning("the leak sensor has fired")
        next_at += period_s
        now = time.monotonic()
        if next_at < now - period_s:
            next_at = now
        time.sleep(max(next_at - now, 0.0))


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line: the URL (default ``sim://``), the rate and an optional duration."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "url", nargs="?", default="sim://", help="the robot's port or URL (default: sim://)"
    )
    parser.add_argument(
        "--rate", type=float, default=2.0, metavar="HZ", help="readings a second (default: 2)"
    )
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="SECONDS",
        help="stop after this long (default: run until Ctrl-C)",
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
    if not 0 < args.rate <= 100:
        parser.error(f"--rate must be in (0, 100] readings a second, got {args.rate:g}")
    if args.duration is not None and not args.duration >= 0:  # (NaN too)
        parser.error(f"--duration must not be negative, got {args.duration:g}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Poll the sensors; exit status 0 when ended by Ctrl-C or ``--duration``, 1 on an error."""
    args = parse_arguments(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    counts = PollCounts()
    try:
        with rovlink.connect(args.url, checksum=args.checksum) as rov:
            print(f"connected to {rov.description}; Ctrl-C stops", flush=True)
            try:
                poll(rov, args.rate, args.duration, counts)
            except KeyboardInterrupt:
                # The driver stays usable after Ctrl-C lands inside a call (that query is
                # abandoned and its late reply fenced off), so the client closes cleanly.
                print("interrupted", flush=True)
            counters = rov.counters
    except (ConnectError, ConnectionLostError) as error:
        log.error("%s", error)
        return 1
    except KeyboardInterrupt:  # while connecting
        print("interrupted", flush=True)
        return 130
    print(
        f"{counts.readings} readings, {counts.missed} missed; {counters.frames_sent} frames sent, "
        f"{counters.timeouts} timeouts, {counters.keepalives} keep-alives",
        flush=True,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
