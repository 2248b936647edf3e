"""Put one robot on an MQTT broker: telemetry, retained state and events out, commands in.

Topics: rovlink/ID/telemetry (JSON readings, QoS 0), rovlink/ID/state (retained; the last will
marks the robot offline), rovlink/ID/events (QoS 1), rovlink/ID/cmd (commands in the console's
words; replies on rovlink/ID/cmd/reply or the request's MQTT 5 response topic). Commands other
than stop are refused unless --allow-commands; without it the bridge is telemetry and sends no
#stop! of its own (at start, at exit). The password is read from --password-file or
the ROVLINK_MQTT_PASSWORD environment variable, never from the command line.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, InputError, UsageError, reason, unreadable

if TYPE_CHECKING:
    from rovlink.bridges.mqtt.broker import BrokerSettings

__all__ = ["EPILOG", "PASSWORD_VARIABLE", "add_broker_options", "broker_settings"]

PASSWORD_VARIABLE = "ROVLINK_MQTT_PASSWORD"

EPILOG = """\
examples:
  rovlink mqtt sim:// --broker mqtt://localhost --robot rov-1
  rovlink mqtt /dev/ttyUSB0 --broker mqtts://fleet.example:8883 --robot rov-7 \\
      --username rov-7 --password-file ~/.rov7-password --cafile fleet-ca.pem --allow-commands
  mosquitto_pub -t rovlink/rov-1/cmd -m 'th 90 30'       (with --allow-commands)
  mosquitto_sub -t 'rovlink/+/state' -v"""


def _rate_hz(text: str) -> float:
    return link_options.bounded_float(text, 0.1, 50.0, " Hz")


def _optional_seconds(text: str) -> float | None:
    value = link_options.seconds(text, maximum=60.0)
    return None if value == 0 else value


def _path(text: str) -> Path:
    return Path(link_options.file_name(text))  # Path("") would be the current directory


def add_broker_options(parser: argparse.ArgumentParser) -> None:
    """The broker's address, credentials and TLS (``mqtt`` and ``fleet`` share them)."""
    group = parser.add_argument_group("broker options")
    group.add_argument(
        "--broker",
        required=True,
        metavar="URL",
        help="mqtt://HOST[:PORT] (1883) or mqtts://HOST[:PORT] (TLS, 8883)",
    )
    group.add_argument("--username", default=None, metavar="NAME", help="broker user name")
    group.add_argument(
        "--password-file",
        type=_path,
        default=None,
        metavar="FILE",
        help=f"a file holding the broker password (or set {PASSWORD_VARIABLE})",
    )
    group.add_argument(
        "--cafile", type=_path, default=None, metavar="FILE", help="TLS: CA certificates to trust"
    )
    group.add_argument(
        "--certfile", type=_path, default=None, metavar="FILE", help="TLS: client certificate"
    )
    group.add_argument(
        "--keyfile", type=_path, default=None, metavar="FILE", help="TLS: client key"
    )
    group.add_argument(
        "--tls-insecure",
        action="store_true",
        help="TLS: accept a certificate that does not name the host (test brokers only)",
    )


def broker_settings(args: argparse.Namespace) -> BrokerSettings:
    """The broker settings from the options; every problem is one line."""
    from rovlink.bridges.mqtt.broker import BrokerSettings, parse_broker_url  # noqa: PLC0415

    try:
        host, port, tls = parse_broker_url(args.broker)
    except ValueError as error:
        raise UsageError(str(error)) from None
    password = os.environ.get(PASSWORD_VARIABLE)
    if args.password_file is not None:
        try:
            password = args.password_file.read_text(encoding="utf-8").strip()
        except (OSError, UnicodeDecodeError) as error:
            raise unreadable(args.password_file, error) from None
    if password is not None and args.username is None:
        raise UsageError("a password needs --username")
    tls_files = [args.cafile, args.certfile, args.keyfile]
    if not tls and (any(tls_files) or args.tls_insecure):
        raise UsageError("TLS options need an mqtts:// broker")
    if args.keyfile is not None and args.certfile is None:
        # A key alone would be dropped unused, and the broker would see no client certificate.
        raise UsageError("--keyfile needs --certfile (the client certificate it is the key of)")
    for path in tls_files:
        if path is not None and not path.is_file():
            raise InputError(f"{path}: no such file")
    if tls:
        _check_tls_files(args)
    return BrokerSettings(
        host,
        port,
        tls,
        args.username,
        password,
        args.cafile,
        args.certfile,
        args.keyfile,
        args.tls_insecure,
    )


def _check_tls_files(args: argparse.Namespace) -> None:
    """Load the TLS files now: a bad one is named here, not reported by every reconnection
    (the bridge retries for ever) as an error of the broker's."""
    import ssl  # noqa: PLC0415

    context = ssl.create_default_context()
    try:
        option, path = "--cafile", args.cafile
        if path is not None:
            context.load_verify_locations(cafile=path)
        option, path = "--certfile", args.certfile
        if path is not None:
            context.load_cert_chain(path, args.keyfile)
    except ssl.SSLError as error:
        what = "PEM certificates" if option == "--cafile" else "a PEM certificate and key"
        raise InputError(f"{option} {path}: not {what} ({error.reason or error})") from None
    except OSError as error:
        raise InputError(f"{option} {path}: cannot read: {reason(error)}") from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``mqtt``'s options."""
    link_options.add_link_options(parser)
    link_options.add_hearing_option(parser)
    add_broker_options(parser)
    group = parser.add_argument_group("bridge options")
    group.add_argument("--robot", required=True, metavar="ID", help="the robot's id: rovlink/ID/…")
    group.add_argument(
        "--rate",
        dest="rate_hz",
        type=_rate_hz,
        default=5.0,
        metavar="HZ",
        help="telemetry readings per second, 0.1–50 (default: %(default)s)",
    )
    group.add_argument(
        "--allow-commands",
        action="store_true",
        help="act on every command of rovlink/ID/cmd, and lock the robot at start and exit "
        "(without it only stop is accepted, and the bridge, telemetry, sends no #stop! of its own)",
    )
    group.add_argument(
        "--motion-timeout",
        dest="motion_timeout_s",
        type=_optional_seconds,
        default=2.0,
        metavar="SECONDS",
        help="zero thrust when th/mvs is not renewed for this long, 0–60; 0: never "
        "(losing the broker zeroes it all the same); motion reaching the bridge later than "
        "this (2 s if 0) is refused (default: %(default)s)",
    )


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C; a controller link that drops is reopened."""
    from rovlink.bridges.mqtt.topics import check_robot_id  # noqa: PLC0415

    try:
        check_robot_id(args.robot)
    except ValueError as error:
        raise UsageError(str(error)) from None
    broker = broker_settings(args)
    with needs_extra("mqtt"):
        import aiomqtt  # noqa: F401, PLC0415 - the mqtt extra
    link_options.check_url(args)
    link_options.client_options(args)
    link_options.log_warnings()
    from rovlink.cli.async_run import serve_async  # noqa: PLC0415 - not on the path of --help

    # (SIGTERM, SIGHUP: a service stopped, status 0; Ctrl-C: 130)
    serve_async(_serve(args, broker), "rovlink mqtt")
    return 0


async def _serve(args: argparse.Namespace, broker: BrokerSettings) -> None:
    import rovlink.aio  # noqa: PLC0415
    from rovlink.bridges.mqtt.bridge import BridgeReplacedError, MqttBridge  # noqa: PLC0415
    from rovlink.bridges.mqtt.command_age import DEFAULT_MAX_COMMAND_AGE_S  # noqa: PLC0415
    from rovlink.cli.interrupt import say_ready  # noqa: PLC0415 - not on the path of --help
    from rovlink.client.errors import ConnectionLostError  # noqa: PLC0415
    from rovlink.piloting.tracked import TrackedClient  # noqa: PLC0415

    # A link that drops (a USB adapter unplugged, a serial server restarting) is reopened: the
    # robot stays on the broker, locked while the link is down.
    options = dataclasses.replace(
        link_options.client_options(args, keepalive_s=1.0, motion_timeout_s=args.motion_timeout_s),
        reconnect=True,
    )
    try:
        client = await rovlink.aio.connect(args.url, baudrate=args.baudrate, options=options)
    except (ConnectionError, OSError) as error:
        raise link_options.connection_failure(args.url, error) from None
    async with contextlib.AsyncExitStack() as leaving:
        if args.allow_commands:
            await leaving.enter_async_context(client)  # (left by an error: #stop! first)
        else:
            # Telemetry leaves the robot as it is, however it ends: the client's own way out
            # on an error (Ctrl-C, SIGTERM) would send #stop! to a robot another tool flies.
            # close() stops only a robot this client moved, which telemetry never does.
            leaving.push_async_callback(client.close)
        await link_options.hear_other_lines_if_asked(args, client)
        bridge = MqttBridge(
            TrackedClient(client, algorithm=args.algorithm),
            broker,
            args.robot,
            rate_hz=args.rate_hz,
            allow_commands=args.allow_commands,
            # Motion that reaches the bridge late is refused beyond the time it would have run.
            max_command_age_s=args.motion_timeout_s or DEFAULT_MAX_COMMAND_AGE_S,
            simulated=link_options.names_simulator(args.url),
        )
        commands = "commands allowed" if args.allow_commands else "only stop accepted"
        say_ready(
            f"rovlink mqtt ready: {args.url} as rovlink/{args.robot} on {broker.describe()} "
            f"({commands}); Ctrl-C stops"
        )
        try:
            await bridge.run()
        except ConnectionLostError as error:
            raise CommandError(f"{args.url}: {error}") from None
        except BridgeReplacedError as error:
            raise CommandError(str(error)) from None
