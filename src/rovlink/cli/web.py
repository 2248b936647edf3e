"""Serve the web ground station: a pilot's screen with gauges, charts, a gamepad and a STOP
button, in any browser on this computer (or, with --host and a token, on the network)."""

from __future__ import annotations

import argparse
import dataclasses

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, UsageError, reason

__all__ = ["EPILOG", "add_arguments", "run"]

EPILOG = """\
examples:
  rovlink web                              the simulator, at http://127.0.0.1:8600/
  rovlink web /dev/ttyUSB0 --checksum      a robot on a serial port
  rovlink web --host 0.0.0.0               on the network: a token URL is printed
  rovlink web --host 0.0.0.0 --token "$ROV_TOKEN"

The page: hold LB (the dead-man) and move the left stick to drive; release it and the thrust
goes to zero. Space or Esc is STOP."""

#: Without ``--port``.
DEFAULT_PORT = 8600
#: How long to wait for the driver on Ctrl-C before giving up on ``#stop!``.
_MOTION_BACKSTOP_S = 1.0


def _port(text: str) -> int:
    return link_options.bounded_int(text, 0, 65535)


def _host(text: str) -> str:
    # uvicorn would take "" as every interface, and print a URL without a host.
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty address")
    return text


def _rate_hz(text: str) -> float:
    return link_options.bounded_float(text, 0.5, 50.0, " Hz")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``web``'s options."""
    link_options.add_link_options(parser)
    link_options.add_hearing_option(parser)
    group = parser.add_argument_group("station options")
    group.add_argument(
        "--host",
        type=_host,
        default="127.0.0.1",
        help="address to serve on; beyond loopback a token is required (default: %(default)s)",
    )
    group.add_argument(
        "--port",
        type=_port,
        default=DEFAULT_PORT,
        help="TCP port, 0 for any free one (default: %(default)s)",
    )
    group.add_argument(
        "--token",
        help="the token pages must present (default: generated when --host is not loopback)",
    )
    group.add_argument(
        "--recordings",
        type=link_options.file_name,
        metavar="DIR",
        default=".",
        help="where the page's record button writes its recordings, which the page can "
        "download (default: the current directory)",
    )
    group.add_argument(
        "--rate",
        dest="rate_hz",
        type=_rate_hz,
        default=10.0,
        metavar="HZ",
        help="sensor polls per second, 0.5–50 (default: %(default)s)",
    )


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C; the robot is sent ``#stop!`` on the way out (unless locked as last
    sent)."""
    with needs_extra("web"):
        from rovlink.cli.async_run import run_async  # noqa: PLC0415
        from rovlink.station import access as station_access  # noqa: PLC0415
        from rovlink.station.hub import telemetry_lost_after  # noqa: PLC0415
        from rovlink.station.serve import (  # noqa: PLC0415
            ServeOptions,
            StationFailedError,
            serve,
        )
    from pathlib import Path  # noqa: PLC0415

    import rovlink.aio  # noqa: PLC0415
    from rovlink.cli.interrupt import say_last, say_ready  # noqa: PLC0415

    link_options.check_url(args)  # (first: a sim:// URL's algorithm is the station's too)
    recordings = Path(args.recordings)
    if recordings.exists() and not recordings.is_dir():  # else refused only at the first recording
        raise UsageError(f"--recordings {args.recordings}: not a directory")
    token = args.token
    if token is None and not station_access.is_loopback(args.host):
        token = station_access.generate_token()
    if token is not None and len(token) < 8:
        raise UsageError("--token must be at least 8 characters")
    # The relay renews a held motion twice a second; the driver expires one not renewed within a
    # second (a second line of defence behind the station's own 300 ms watchdog). The
    # keep-alive runs on the station's event loop: a hung station stops feeding the
    # controller's link-loss failsafe (P17), which then stops the robot.
    client_options = dataclasses.replace(
        link_options.client_options(args, keepalive_s=1.0, motion_timeout_s=_MOTION_BACKSTOP_S),
        reconnect=True,
    )
    options = ServeOptions(
        host=args.host,
        port=args.port,
        token=token,
        rate_hz=args.rate_hz,
        algorithm=args.algorithm,
        recordings_dir=recordings,  # made when the first recording starts
        telemetry_lost_s=telemetry_lost_after(client_options.timeout_s),
    )
    link_options.log_warnings()  # cuts, leaks and lost links also reach the terminal

    async def connect() -> rovlink.aio.AsyncClient:
        try:
            client = await rovlink.aio.connect(
                args.url, baudrate=args.baudrate, options=client_options
            )
        except (ConnectionError, OSError) as error:
            raise link_options.connection_failure(args.url, error) from None
        try:
            await link_options.hear_other_lines_if_asked(args, client)
        except BaseException:
            await client.close()
            raise
        return client

    def ready(urls: list[str]) -> None:
        say_ready(f"rovlink web ready: {args.url} at " + " or ".join(urls) + "; Ctrl-C stops")

    try:
        ending = run_async(serve(connect, options, description=args.url, ready=ready))
    except OSError as error:
        raise CommandError(f"cannot serve on {args.host}:{args.port}: {reason(error)}") from None
    except StationFailedError as error:  # (its traceback is logged: a bug)
        raise CommandError(f"{error}: the station shut down") from None
    if ending == "interrupted":  # Ctrl-C: status 130, as every command
        raise KeyboardInterrupt
    if ending == "stopped":  # SIGTERM, SIGHUP: a service stopped, 0
        say_last("rovlink web stopped")
    return 0
