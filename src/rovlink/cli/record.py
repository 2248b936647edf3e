"""Record a link to a file without driving it: every byte both ways, the frames, the events and
the telemetry table. With --tap, a program talks to the controller through rovlink (a TCP port
or a pseudo-terminal) and both directions are recorded; without it, rovlink only listens (a
sniffer on a line that another program drives). The format follows the file's suffix: .mcap
(Foxglove), .jsonl, .csv (telemetry) or .bin (raw wire)."""

from __future__ import annotations

import argparse
import sys
import threading
import time

from rovlink.cli.failure import CommandError, UsageError, reason
from rovlink.cli.link_options import (
    DEFAULT_REPLY_TIMEOUT_S,
    add_checksum_options,
    baud_rate,
    file_name,
    reply_timeout,
    seconds,
)
from rovlink.cli.output_file import check_writable
from rovlink.cli.recording import (
    add_rotation_options,
    check_recording_name,
    discard_empty_recording,
    open_recorder,
    recorded_nothing,
    refuse_existing_recording,
    report_recording,
)
from rovlink.cli.tcp_endpoint import refuse_remote

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink record /dev/ttyUSB0 -o dive.mcap --tap socket://127.0.0.1:5761
      (then point the pilot's program at socket://127.0.0.1:5761)
  rovlink record socket://192.168.2.2:5760 -o dive.mcap --tap pty --split 10m
  rovlink record /dev/ttyUSB1 -o line.bin          a sniffer port: listen only"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``record``'s arguments."""
    parser.add_argument(
        "url", metavar="URL", help="the controller's port: /dev/ttyUSB0, socket://…"
    )
    parser.add_argument(
        "-o",
        "--output",
        required=True,
        type=file_name,
        metavar="FILE",
        help="the recording (.mcap, .jsonl, .csv, .bin); a file already there is refused",
    )
    parser.add_argument(
        "--tap",
        metavar="ENDPOINT",
        help="serve the controller to another program through ENDPOINT (socket://HOST:PORT or "
        "pty) and record both directions; without it, only listen",
    )
    parser.add_argument(
        "--baudrate", type=baud_rate, metavar="BAUD", help="serial speed (default 115200)"
    )
    parser.add_argument(
        "--duration", type=seconds, metavar="SECONDS", help="stop after this long (default: Ctrl-C)"
    )
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="let --tap socket:// use an address other computers reach; the protocol has no "
        "authentication, so anyone who reaches it drives the robot",
    )
    parser.add_argument(
        "--exit-on-loss",
        action="store_true",
        help="end (status 1) when the controller's link is lost, for a service manager to "
        "restart; by default it is reopened, the recording and the tap's program going on",
    )
    parser.add_argument(
        "--reply-timeout",
        dest="reply_timeout_s",
        type=reply_timeout,
        default=DEFAULT_REPLY_TIMEOUT_S,
        metavar="SECONDS",
        help="how long the program waits for a reply (its --timeout): a reply after that is "
        "recorded as late, not matched to a later query of its name (default: %(default)s)",
    )
    add_checksum_options(parser, "the link starts in checksum mode (to decode its frames)")
    add_rotation_options(parser)


def run(args: argparse.Namespace) -> int:
    """Record until Ctrl-C, SIGTERM, SIGHUP or ``--duration``; the file is finished in every
    case. A link lost before any frame came (a controller that is busy, a connection closed at
    once) did not open: status 1, and no file is kept. A link lost later is reopened at the same
    URL, a ``link`` event marking the loss and the return; with ``--exit-on-loss`` it ends the
    recording with status 1 (as ``rovlink send`` ends on a lost link), the file kept."""
    from rovlink.cli.interrupt import ServingSignals, say_ready  # noqa: PLC0415
    from rovlink.client import parse_url  # noqa: PLC0415 - the driver loads when used
    from rovlink.client.errors import ConnectionLostError  # noqa: PLC0415
    from rovlink.client.events import LinkState  # noqa: PLC0415
    from rovlink.client.links import open_link  # noqa: PLC0415
    from rovlink.recorder.reopening import ReopeningLink  # noqa: PLC0415
    from rovlink.recorder.tap import forward, parse_tap  # noqa: PLC0415

    try:
        endpoint = parse_url(args.url, args.baudrate)
    except ValueError as error:
        raise UsageError(f"URL: {error}") from None
    # Before the link opens (a board may reset as its port opens) and the tap is served.
    check_recording_name(args.output)  # (a name of no format: status 2, whether it exists or not)
    refuse_existing_recording(args, args.output)
    check_writable("-o", args.output)
    _refuse_a_remote_tap(args)
    try:
        tap = parse_tap(args.tap) if args.tap is not None else None  # '' is refused there
    except ValueError as error:
        raise UsageError(str(error)) from None
    except OSError as error:
        raise CommandError(f"cannot serve the tap {args.tap}: {reason(error)}") from None
    try:
        first_link = open_link(endpoint)
    except (ConnectionError, OSError) as error:
        if tap is not None:
            tap.close()
        from rovlink.cli.link_options import connection_failure  # noqa: PLC0415

        raise connection_failure(args.url, error) from None
    from rovlink.cli.link_options import log_warnings  # noqa: PLC0415

    log_warnings()  # (a recording that stops, a lost link: on stderr)
    # (--checksum: the link is in checksum mode already, as the recording starts.)
    recorder = open_recorder(
        args, args.output, url=args.url, program="rovlink record", checksum=args.checksum
    )
    signals = ServingSignals()
    stopping = signals.stopping
    heard = _FirstWords()
    answered = _FirstWords()  # (the controller's side alone)

    def link_changed(state: str, detail: str) -> None:
        recorder.on_event(LinkState(time.monotonic(), state, detail))

    # (A controller that closed before a frame came from it turned us away: no use reopening.)
    link = ReopeningLink(
        first_link,
        lambda: open_link(endpoint),
        stopping=stopping,
        on_change=link_changed,
        may_reopen=lambda: answered.frame and not args.exit_on_loss,
    )

    def record(direction: str, data: bytes, *, by_session: bool = False) -> None:
        heard.add(data)
        if direction == "in":
            answered.add(data)
        recorder.on_bytes(direction, data, by_session=by_session)

    where = f"; program's side: {tap.path}" if tap is not None else " (listening only)"
    say_ready(f"recording {args.url} to {args.output}{where}; Ctrl-C stops", stream=sys.stderr)
    started_s = time.monotonic()
    lost: str | None = None
    try:
        if args.duration is not None:
            timer = threading.Timer(args.duration, stopping.set)
            timer.daemon = True
            timer.start()
        if tap is not None:
            forward(tap, link, record, stopping, checksum=args.checksum, algorithm=args.algorithm)
        else:
            while not stopping.is_set():
                data = link.read_available(0.1)
                if data:
                    record("in", data)
    except ConnectionLostError as error:
        lost = str(error)
        # In the file too: read later, it must not look like one stopped by hand.
        link_changed("lost", lost)
    finally:
        link.close()
        if tap is not None:
            tap.close()
        recorder.close()
        # (Only now: a second signal, taken as Ctrl-C after this, must not cut the file short.)
        signals.restore()
    if lost is not None and not heard.frame:
        # Nothing but text came (a busy controller says so, then closes): not a recording.
        discard_empty_recording(recorder, "rovlink record")
        raise CommandError(f"{args.url}: {lost} before any frame came{heard.said()}")
    if recorded_nothing(recorder):
        discard_empty_recording(recorder, "rovlink record")
    else:
        report_recording(recorder, time.monotonic() - started_s)
    if lost is not None:
        raise CommandError(f"{lost}; the recording ends here")
    signals.say_stopped("rovlink record")  # (not after --duration: its end is no news)
    signals.finish()  # (Ctrl-C: status 130)
    return 1 if recorder.error else 0


def _refuse_a_remote_tap(args: argparse.Namespace) -> None:
    """As ``rovlink fault`` and ``rovlink controller``: a tap on an address other computers
    reach lets anyone there drive the robot, unauthenticated, unless ``--allow-remote``."""
    if args.tap is None or not args.tap.startswith("socket://"):
        return
    host = args.tap[len("socket://") :].rpartition(":")[0] or "127.0.0.1"
    refuse_remote("--tap", args.tap, host, allow_remote=args.allow_remote)


class _FirstWords:
    """Whether a frame has come on the link yet, and the text that came before one (what a
    controller that turns us away says: "busy: ..."), kept up to a bound."""

    _LIMIT_BYTES = 4096

    def __init__(self) -> None:
        self.frame = False
        self._text = bytearray()

    def add(self, data: bytes) -> None:
        if self.frame:
            return
        if b"!" in data:  # (the end of a frame; text never holds one, P5)
            self.frame = True
            self._text.clear()
        elif len(self._text) < self._LIMIT_BYTES:
            self._text += data[: self._LIMIT_BYTES - len(self._text)]

    def said(self) -> str:
        """``; it said: "<the last line>"``, or nothing if no text came."""
        from rovlink.protocol.visible import visible  # noqa: PLC0415

        lines = [line.strip() for line in bytes(self._text).decode("latin-1").splitlines()]
        lines = [line for line in lines if line]
        return f'; it said: "{visible(lines[-1])}"' if lines else ""
