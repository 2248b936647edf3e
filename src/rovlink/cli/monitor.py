"""Live depth, attitude, leak alarm, link health and a depth chart; keys drive the robot.

space stops, s starts, arrows set direction and power, PgUp/PgDn the depth target, o/c the
claw, r resets the leak latch, q quits (sending #stop! unless locked as last sent).
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.failure import CommandError, UsageError

if TYPE_CHECKING:
    from rovlink.aio import AsyncClient
    from rovlink.client.options import StrayCallback
    from rovlink.monitor.app import MonitorApp

__all__ = ["EPILOG", "build_app"]

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
    parser.add_argument(
        "--rate",
        dest="rate_hz",
        type=_rate_hz,
        default=5.0,
        metavar="HZ",
        help="sensor polls per second, 0.1–100 (default: %(default)s)",
    )


def build_app(args: argparse.Namespace) -> MonitorApp:
    """The monitor for the parsed options, connecting when it starts (the options are checked
    now)."""
    return _build(args)[0]


def _build(args: argparse.Namespace) -> tuple[MonitorApp, list[Exception]]:
    """The monitor, and where the reason lands if its port cannot be opened."""
    try:
        from rovlink.monitor.app import MonitorApp  # noqa: PLC0415 - textual loads only here
    except ImportError as error:
        raise CommandError(f"needs {error.name}: pip install 'rovlink[monitor]'") from None

    connect = link_options.connect_async(args)
    failures: list[Exception] = []

    async def connect_or_leave(on_stray: StrayCallback) -> AsyncClient:
        # A port that cannot be opened ends the command: the dashboard would show "could not
        # connect" and wait for ever.
        try:
            return await connect(on_stray)
        except (ConnectionError, ValueError, OSError) as error:
            failures.append(error)
            app.exit(return_code=1)
            raise

    app = MonitorApp(
        connect_or_leave,
        description=args.url,
        rate_hz=args.rate_hz,
        algorithm=args.algorithm,
    )
    return app, failures


def run(args: argparse.Namespace) -> int:
    """Run the dashboard until the user quits."""
    app, failures = _build(args)
    app.run()
    for failure in failures:
        if isinstance(failure, ValueError):
            raise UsageError(str(failure))
        raise link_options.connection_failure(args.url, failure)
    return 0
