"""Serve the robot as an ArduSub-like MAVLink vehicle for QGroundControl, MAVProxy or pymavlink.

Telemetry out (HEARTBEAT, SYS_STATUS, ATTITUDE, VFR_HUD, GLOBAL_POSITION_INT, SCALED_PRESSURE2,
SYSTEM_TIME), parameters, arming, MANUAL/ALT_HOLD and the joystick in. No ground-station
heartbeat or joystick input for 3 s while armed stops the robot; joystick input stale for 1 s
zeroes its thrust; a stick or RC channel off centre at arming is held at neutral until centred.
The robot is left locked when the bridge ends.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, InputError, UsageError, reason, unreadable

if TYPE_CHECKING:
    from rovlink.bridges.mavlink.parameters import ParameterTable

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink mavlink sim://                                  QGroundControl on this machine
  rovlink mavlink /dev/ttyUSB0 --out udpout:192.168.2.1:14550
  rovlink mavlink sim:// --out udpin:0.0.0.0:14550        wait for a ground station
  rovlink mavlink sim:// --out tcpin:127.0.0.1:5760 --params robot.param"""


def _system_id(text: str) -> int:
    return link_options.bounded_int(text, 1, 255)


def _path(text: str) -> Path:
    return Path(link_options.file_name(text))  # Path("") would be the current directory


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``mavlink``'s options."""
    link_options.add_link_options(parser)
    link_options.add_hearing_option(parser)
    group = parser.add_argument_group("MAVLink options")
    group.add_argument(
        "--out",
        default="udpout:127.0.0.1:14550",
        metavar="ENDPOINT",
        help="udpout:HOST:PORT (send to a ground station; QGroundControl listens on "
        "14550), udpin:HOST:PORT, tcpin:HOST:PORT or tcp:HOST:PORT (default: %(default)s)",
    )
    group.add_argument(
        "--system-id",
        type=_system_id,
        default=1,
        metavar="N",
        help="the vehicle's MAVLink system id, 1–255 (default: %(default)s)",
    )
    group.add_argument(
        "--params",
        type=_path,
        default=None,
        metavar="FILE",
        help="parameter file as ground stations save them (MAVProxy's NAME VALUE lines or "
        "QGroundControl's tab-separated ones): its values are sent to the controller on start",
    )


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C; a controller link that drops is reopened."""
    try:
        from rovlink.bridges.mavlink.endpoint import check_address  # noqa: PLC0415
        from rovlink.bridges.mavlink.parameters import (  # noqa: PLC0415
            ParameterError,
            ParameterTable,
            read_parameter_file,
        )
    except ImportError as error:  # pragma: no cover - the package is part of rovlink
        raise CommandError(str(error)) from None
    try:
        check_address(args.out)
    except ValueError as error:
        raise UsageError(str(error)) from None
    values: dict[str, int] = {}
    if args.params is not None:
        try:
            # (utf-8-sig: a byte order mark, as Windows editors save one, is not a name's start)
            text = args.params.read_text(encoding="utf-8-sig")
        except (OSError, UnicodeDecodeError) as error:
            raise unreadable(args.params, error) from None
        try:
            values = read_parameter_file(text, str(args.params))
        except ParameterError as error:
            raise InputError(str(error)) from None
    with needs_extra("mavlink"):
        import pymavlink  # noqa: F401, PLC0415 - the mavlink extra
    link_options.check_url(args)
    link_options.client_options(args)
    link_options.log_warnings()
    from rovlink.cli.async_run import serve_async  # noqa: PLC0415 - not on the path of --help

    # (SIGTERM, SIGHUP: a service stopped, status 0; Ctrl-C: 130)
    serve_async(_serve(args, ParameterTable(_defaults() | values), list(values)), "rovlink mavlink")
    return 0


def _defaults() -> dict[str, int]:
    """The rovlink controller's reset values: what the table shows until something is set."""
    from rovlink.controller.config import ControllerConfig  # noqa: PLC0415

    config = ControllerConfig()
    return {
        "RL_DEPTH_P": config.depth_pid.kp,
        "RL_DEPTH_I": config.depth_pid.ki,
        "RL_DEPTH_D": config.depth_pid.kd,
        "RL_MAX_PWM": config.max_pwm,
        "RL_DEPTH_ZERO": config.depth.zero_raw,
        "RL_DEPTH_K": config.depth.k,
    }


async def _serve(
    args: argparse.Namespace, parameters: ParameterTable, send_on_start: list[str]
) -> None:
    import rovlink.aio  # noqa: PLC0415
    from rovlink.bridges.mavlink.bridge import MavlinkBridge  # noqa: PLC0415
    from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint  # noqa: PLC0415
    from rovlink.cli.interrupt import say_ready  # noqa: PLC0415 - not on the path of --help
    from rovlink.client.errors import ConnectionLostError  # noqa: PLC0415
    from rovlink.piloting.tracked import TrackedClient  # noqa: PLC0415

    # A link that drops (a USB adapter unplugged, a serial server restarting) is reopened: the
    # ground station keeps its vehicle, disarmed while the link is down.
    options = dataclasses.replace(
        link_options.client_options(args, keepalive_s=1.0), reconnect=True
    )
    try:
        client = await rovlink.aio.connect(args.url, baudrate=args.baudrate, options=options)
    except (ConnectionError, OSError) as error:
        raise link_options.connection_failure(args.url, error) from None
    async with client:
        await link_options.hear_other_lines_if_asked(args, client)
        try:
            endpoint = MavlinkEndpoint(args.out, system_id=args.system_id)
        except OSError as error:
            raise CommandError(f"cannot open {args.out}: {reason(error)}") from None
        bridge = MavlinkBridge(
            TrackedClient(client, algorithm=args.algorithm),
            endpoint,
            parameters,
            send_on_start=send_on_start,
        )
        say_ready(
            f"rovlink mavlink ready: {args.url} as MAVLink system {args.system_id} on "
            f"{args.out}; Ctrl-C stops"
        )
        try:
            await bridge.run()
        except ConnectionLostError as error:
            raise CommandError(f"{args.url}: {error}") from None
