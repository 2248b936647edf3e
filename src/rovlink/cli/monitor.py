"""Live depth, attitude, leak alarm, link health and a depth chart; keys drive the robot.

space stops, s starts, arrows set direction and power, PgUp/PgDn the depth target, o/c the
claw, r resets the leak latch, q quits (sending #stop! unless locked as last sent).
It needs a terminal: its keys come from standard input, its dashboard goes to standard output.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import sys
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import NoTerminalError, UsageError, is_terminal

if TYPE_CHECKING:
    from rovlink.aio import AsyncClient
    from rovlink.client.options import StrayCallback
    from rovlink.monitor.app import Connector, MonitorApp
    from rovlink.protocol import Event

__all__ = ["EPILOG", "build_app", "missing_terminal", "undrawable_encoding"]

EPILOG = """\
examples:
  rovlink monitor                      on the simulator
  rovlink monitor 'sim://?leak_at=5'   try a leak
  rovlink monitor /dev/ttyUSB0 --checksum --rate 10"""


def _rate_hz(text: str) -> float:
    return link_options.bounded_float(text, 0.1, 100.0, " Hz")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``monitor``'s options."""
    link_options.add_link_options(parser)
    link_options.add_hearing_option(parser)
    parser.add_argument(
        "--rate",
        dest="rate_hz",
        type=_rate_hz,
        default=5.0,
        metavar="HZ",
        help="sensor polls per second, 0.1–100 (default: %(default)s)",
    )


def build_app(
    args: argparse.Namespace,
    connector: Connector | None = None,
) -> MonitorApp:
    """The monitor for the parsed options, with ``connector`` giving it its client (default:
    it connects when it starts; the options are checked now)."""
    return _monitor_app_class()(
        connector or link_options.connect_async(args),
        description=args.url,
        rate_hz=args.rate_hz,
        algorithm=args.algorithm,
    )


def _monitor_app_class() -> type[MonitorApp]:
    with needs_extra("monitor"):
        from rovlink.monitor.app import MonitorApp  # noqa: PLC0415 - textual loads only here
    return MonitorApp


def missing_terminal() -> str | None:
    """What the dashboard lacks to run, or ``None``: standard input, output and error all a
    terminal. It reads its keys (space, the stop, among them) from standard input, and textual
    draws it on standard error.

    Without a terminal (run from a script, its output to a file) it would write escape
    sequences until killed, and no key, not even the stop, could reach it. With standard error
    alone sent elsewhere (``2>monitor.log``, ``2>/dev/null``) the keys drove the robot from a
    blank screen, the dashboard drawn into the file.
    """
    streams = (
        ("standard input", sys.stdin),
        ("standard output", sys.stdout),
        ("standard error", sys.stderr),
    )
    missing = [name for name, stream in streams if not is_terminal(stream)]
    if not missing:
        return None
    names = missing[0] if len(missing) == 1 else f"{', '.join(missing[:-1])} and {missing[-1]}"
    return f"{names} {'is' if len(missing) == 1 else 'are'} not a terminal"


#: Characters the dashboard draws with: boxes, bars, the compass tape, arrows and units.
_DRAWN_CHARACTERS = "╭─│╰━┃▲●┼·°—←→↑↓⭘"


def undrawable_encoding() -> str | None:
    """The encoding of the terminal the dashboard draws on (textual draws on standard error)
    if it cannot show the dashboard's characters, as in a locale that is not UTF-8; else
    ``None``. There every box and arrow would come out as an escape, ``\\u2500``."""
    encoding = getattr(sys.__stderr__, "encoding", None)
    if not isinstance(encoding, str):
        return None
    try:
        _DRAWN_CHARACTERS.encode(encoding)
    except (UnicodeEncodeError, LookupError):
        return encoding
    return None


def _refuse_without_terminal() -> None:
    missing = missing_terminal()
    if missing is not None:
        raise NoTerminalError(
            f"needs a terminal for its dashboard and keys, but {missing}; without one, "
            "read the sensors with 'rovlink send URL qsa', or record the link with "
            "'rovlink record URL -o FILE'"
        )
    encoding = undrawable_encoding()
    if encoding is not None:
        raise NoTerminalError(
            f"the terminal's encoding, {encoding}, cannot show the dashboard's boxes and "
            "arrows; run it in a UTF-8 locale, e.g. LC_ALL=C.UTF-8"
        )


class _StrayRelay:
    """The ``on_stray`` of a client opened before its dashboard: what the controller sends
    before the dashboard listens is kept for it."""

    def __init__(self) -> None:
        self._target: StrayCallback | None = None
        self._early: list[Event] = []

    def __call__(self, event: Event) -> None:
        if self._target is None:
            self._early.append(event)
        else:
            self._target(event)

    def forward_to(self, target: StrayCallback) -> None:
        self._target = target
        for event in self._early:
            target(event)
        self._early.clear()


async def _connect_then_show(args: argparse.Namespace) -> int:
    """Run the dashboard; the exit status: 1 if leaving found the link lost, unlocked (the
    ``#stop!`` unsent, said here), or if the dashboard failed (textual has shown the error; the
    link's worker, cancelled, stopped the robot), else 0."""
    from rovlink.cli.async_run import StopOnTermination  # noqa: PLC0415 - as run_async

    # The port is opened first, as by every other command: one that is busy or missing is one
    # line on stderr, not a dashboard drawn and taken down again.
    _monitor_app_class()  # (a missing extra is said before the port is opened)
    link_options.check_url(args)  # (a malformed URL is said first, as by every command)
    _refuse_without_terminal()  # before the port opens, or a recording's file is made
    connect = link_options.connect_async(args)
    relay = _StrayRelay()
    try:
        client = await connect(relay)
    except ValueError as error:
        raise UsageError(str(error)) from None
    except (ConnectionError, OSError) as error:
        raise link_options.connection_failure(args.url, error) from None

    async def connected(on_stray: StrayCallback) -> AsyncClient:
        relay.forward_to(on_stray)
        return client

    # A closed terminal can block textual, and so this loop, for ever: a signal then stops the
    # robot and ends the process without it (see StopOnTermination).
    with StopOnTermination(client.emergency_stop, "rovlink monitor"):
        try:
            await link_options.hear_other_lines_if_asked(args, client)
            app = build_app(args, connected)
            try:
                # No mouse reporting: the mouse drives nothing (see MonitorApp.on_event), and the
                # terminal keeps its own text selection.
                await app.run_async(mouse=False)
            finally:
                if app.stop_unsent is not None:  # (once the dashboard has left the terminal)
                    with contextlib.suppress(OSError):  # (a terminal that hung up)
                        print(f"rovlink monitor: {app.stop_unsent}", file=sys.stderr)
        finally:
            if not client.closed:
                await client.close()
    return 1 if app.stop_unsent is not None or app.return_code else 0


def run(args: argparse.Namespace) -> int:
    """Connect, then run the dashboard until the user quits."""
    from rovlink.cli.async_run import run_async  # noqa: PLC0415 - not on the path of --help

    try:
        # (1 after q with the link lost, unlocked, or a failure: the status tells a script.)
        return run_async(_connect_then_show(args))
    except OSError as error:
        if error.errno != errno.EIO:
            raise
        raise KeyboardInterrupt from None  # its terminal hung up: ended as by Ctrl-C
