"""Run the controller on a board and serve the protocol on its serial line (or a PTY, or TCP).

--board pi drives real hardware as rov.toml describes it (a PCA9685 for the ESCs and the claw,
an MS5837 or an analog transducer for pressure, a BNO055, a leak probe on a GPIO); --board sim
is the simulated robot, so one command line serves both. The protocol has no authentication:
whoever reaches the line drives the robot, so TCP listens on loopback unless --allow-remote."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Protocol

from rovlink.cli.failure import CommandError, InputError, UsageError, reason
from rovlink.cli.interrupt import ServingSignals, say_last, say_ready
from rovlink.cli.link_options import baud_rate, file_name, seconds
from rovlink.cli.tcp_endpoint import listen_address, refuse_remote, tcp_endpoint

if TYPE_CHECKING:
    from rovlink.board.pi.config import PiConfig
    from rovlink.board.server import BoardServer

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink controller --board pi --config rov.toml --port /dev/serial0
  rovlink controller --board pi --config rov.toml --pty --tcp 5760
  rovlink controller --board sim --tcp 5760
  rovlink controller --board pi --config rov.toml --tcp 0.0.0.0:5760 --allow-remote
  rovlink controller --board pi --config rov.toml --neutral   # systemd's ExecStopPost

docs/hardware.md has the wiring, a complete rov.toml and a systemd unit."""

_DEFAULT_BAUD = 115200  # P19
#: rov.toml tables that belong to the board, not to the simulator.
_BOARD_TABLES = ("i2c", "pca9685", "esc", "claw", "pressure", "imu", "leak", "board")


def _watchdog_seconds(text: str) -> float:
    return seconds(text, maximum=3600.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``controller``'s options."""
    parser.add_argument(
        "--board",
        choices=("pi", "sim"),
        default="pi",
        help="pi: real hardware per --config; sim: the simulated robot (default: %(default)s)",
    )
    parser.add_argument(
        "--config",
        type=file_name,
        metavar="FILE",
        help="rov.toml: the controller's tables and the board's (required for --board pi)",
    )
    parser.add_argument(
        "--port",
        type=file_name,
        metavar="DEVICE",
        help="serve on this serial device, e.g. /dev/serial0",
    )
    parser.add_argument(
        "--baud",
        "--baudrate",
        dest="baud",
        type=baud_rate,
        metavar="BAUD",
        help=f"--port's rate, 8N1 (default: {_DEFAULT_BAUD})",
    )
    parser.add_argument(
        "--pty", action="store_true", help="serve on a pseudo-terminal (its path is printed)"
    )
    parser.add_argument(
        "--tcp",
        metavar="[HOST:]PORT",
        help="listen on TCP, one client at a time (host 127.0.0.1 unless given)",
    )
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="let --tcp listen on an address other computers reach; the protocol has no "
        "authentication, so anyone who reaches it drives the robot",
    )
    parser.add_argument(
        "--neutral",
        action="store_true",
        help="set the thrusters to neutral on the PWM board and exit, serving nothing: after "
        "a controller that could not (killed, crashed), e.g. as systemd's ExecStopPost",
    )
    parser.add_argument(
        "--watchdog",
        type=_watchdog_seconds,
        metavar="SECONDS",
        help="link-loss failsafe timeout (default: from the config, 2 s); --board pi: "
        "0.1–10 s, --board sim: 0 turns it off",
    )


def run(args: argparse.Namespace) -> int:
    """Serve until SIGTERM or Ctrl-C; the thrusters end at neutral however it ends."""
    if args.neutral:
        return _set_neutral(args)
    address = _tcp_address(args)
    if args.baud is not None and args.port is None:
        # (Silently unused before: a pseudo-terminal or a TCP socket has no rate.)
        paced = "; rovlink sim --baud paces a simulated line" if args.board == "sim" else ""
        raise UsageError(f"--baud is the rate of --port's serial device{paced}")
    if args.port is None and not args.pty and address is None:
        if args.board == "pi":
            raise UsageError("give --port DEVICE, --pty and/or --tcp [HOST:]PORT to serve on")
        args.pty = True
    _configure_logging()
    signals = ServingSignals()
    try:
        if args.board == "sim":
            status = _run_sim(args, address, signals)
        else:
            status = _run_pi(args, address, signals)
    finally:
        signals.restore()
    signals.finish()  # (Ctrl-C: status 130; SIGTERM, SIGHUP: a service stopped, 0)
    return status


def _set_neutral(args: argparse.Namespace) -> int:
    """``--neutral``: the thrusters at neutral, and nothing else opened."""
    from rovlink.board.board import BoardStartError  # noqa: PLC0415
    from rovlink.board.pi.board import PwmBoardInUseError, set_pi_outputs_at_rest  # noqa: PLC0415

    if args.board != "pi":
        raise UsageError("--neutral is for --board pi")
    if args.port is not None or args.pty or args.tcp is not None:
        raise UsageError("--neutral serves nothing: leave out --port, --pty and --tcp")
    _configure_logging()
    config = _pi_outputs_config(args)
    try:
        done = set_pi_outputs_at_rest(config)
    except PwmBoardInUseError as error:  # a running controller sets its thrusters itself
        raise CommandError(str(error)) from None
    except BoardStartError as error:
        raise CommandError(f"{error}; NEUTRAL COULD NOT BE SET: cut the thruster power") from None
    say_last(f"rovlink controller: {done}")
    return 0


def _tcp_address(args: argparse.Namespace) -> tuple[str, int] | None:
    if args.tcp is None:
        return None
    from rovlink.controller.lines import parse_tcp_address  # noqa: PLC0415

    try:
        host, port = parse_tcp_address(args.tcp)
    except ValueError as error:
        raise UsageError(f"--tcp: {error}") from None
    refuse_remote("--tcp", args.tcp, host, allow_remote=args.allow_remote)
    return host, port


def _run_pi(
    args: argparse.Namespace, address: tuple[str, int] | None, signals: ServingSignals
) -> int:
    import logging  # noqa: PLC0415

    from rovlink.board.board import BoardStartError  # noqa: PLC0415
    from rovlink.board.pi.board import open_pi_board  # noqa: PLC0415
    from rovlink.board.server import BoardServer  # noqa: PLC0415
    from rovlink.board.service_notify import ServiceNotifier  # noqa: PLC0415

    config = _pi_config(args)
    try:
        board = open_pi_board(config)
    except BoardStartError as error:
        raise CommandError(str(error)) from None
    service_notifier = ServiceNotifier.from_environment()  # (Type=notify, WatchdogSec=)
    server = BoardServer(
        config.controller,
        board,
        overrun_warning_s=config.board.overrun_warning_s,
        service_notifier=service_notifier,
    )
    try:
        endpoints = _open_endpoints(server, args, address)
        degraded = "".join(f"; {warning}" for warning in board.warnings)
        say_ready(
            f"rovlink controller ready: board pi, {', '.join(endpoints)}; "
            f"thrusters at neutral{degraded}; Ctrl-C stops"
        )
        if service_notifier is not None:
            service_notifier.ready()
        try:
            server.serve(signals.stopping.is_set)
        except Exception as error:
            logging.getLogger("rovlink.board").exception("the control loop failed")
            outcome = (
                "thrusters set to neutral"
                if server.at_rest
                else "NEUTRAL COULD NOT BE SET: cut the thruster power"
            )
            found = f"; {server.failure_diagnosis}" if server.failure_diagnosis else ""
            raise CommandError(
                f"the control loop failed ({type(error).__name__}: {error}); {outcome}{found}"
            ) from None
    finally:
        if not server.at_rest:
            server.make_safe()
        server.close()
        if service_notifier is not None:
            service_notifier.close()
    schedule = server.schedule
    signals.say_stopped(  # (a closed terminal, SIGHUP, takes no line)
        "rovlink controller",
        f"thrusters at neutral; {schedule.periods} control periods, "
        f"{schedule.overruns} overrun(s), {server.device_faults} device fault(s)",
    )
    return 0


def _open_endpoints(
    server: BoardServer, args: argparse.Namespace, address: tuple[str, int] | None
) -> list[str]:
    """Open the serial device, the PTY and the TCP listener asked for; their descriptions."""
    endpoints = []
    if args.port is not None:
        import serial  # noqa: PLC0415

        baud = args.baud if args.baud is not None else _DEFAULT_BAUD
        try:
            server.open_serial(args.port, baud)
        except (serial.SerialException, OSError, ValueError) as error:
            raise CommandError(f"cannot open {args.port}: {error}") from None
        endpoints.append(f"serial {args.port} {baud} baud")
    return endpoints + _open_pty_and_tcp(server, args, address)


class _LineServer(Protocol):
    def open_pty(self) -> str: ...
    def listen_tcp(self, host: str, port: int) -> tuple[str, int]: ...


def _open_pty_and_tcp(
    server: _LineServer, args: argparse.Namespace, address: tuple[str, int] | None
) -> list[str]:
    """Open the PTY and the TCP listener asked for (a board or the simulator); their
    descriptions."""
    endpoints = []
    if args.pty:
        endpoints.append(f"pty {server.open_pty()}")
    if address is not None:
        try:
            host, port = server.listen_tcp(*address)
        except OSError as error:
            where = listen_address(*address)
            raise CommandError(f"cannot listen on {where}: {reason(error)}") from None
        endpoints.append(tcp_endpoint(host, port, "rovlink.board"))
    return endpoints


def _pi_config(args: argparse.Namespace) -> PiConfig:
    import dataclasses  # noqa: PLC0415

    from rovlink.board.pi.config import load_pi_config  # noqa: PLC0415
    from rovlink.controller import ConfigError  # noqa: PLC0415

    if args.config is None:
        raise UsageError("--board pi needs --config rov.toml (see docs/hardware.md)")
    try:
        config = load_pi_config(args.config)
    except ConfigError as error:
        raise InputError(str(error)) from None
    if args.watchdog is not None:
        from rovlink.board.watchdog_bounds import board_watchdog_problem  # noqa: PLC0415

        problem = board_watchdog_problem(args.watchdog)
        if problem is not None:
            raise UsageError(f"--watchdog {problem}")
        controller = dataclasses.replace(config.controller, watchdog_s=args.watchdog)
        config = dataclasses.replace(config, controller=controller)
    return config


def _pi_outputs_config(args: argparse.Namespace) -> PiConfig:
    """What ``--neutral`` needs of rov.toml: the PWM boards' tables only, so that a mistake
    in another table cannot leave the thrusters of a dead controller running."""
    from rovlink.board.pi.config import load_pi_outputs_config  # noqa: PLC0415
    from rovlink.controller import ConfigError  # noqa: PLC0415

    if args.config is None:
        raise UsageError("--board pi needs --config rov.toml (see docs/hardware.md)")
    try:
        return load_pi_outputs_config(args.config)
    except ConfigError as error:
        raise InputError(f"{error}; NEUTRAL COULD NOT BE SET: cut the thruster power") from None


def _run_sim(
    args: argparse.Namespace, address: tuple[str, int] | None, signals: ServingSignals
) -> int:
    import dataclasses  # noqa: PLC0415

    from rovlink.controller import ConfigError  # noqa: PLC0415
    from rovlink.controller.config import read_toml  # noqa: PLC0415
    from rovlink.sim.robot import SimConfig, sim_config_from_mapping  # noqa: PLC0415
    from rovlink.sim.server import SimServer  # noqa: PLC0415

    if args.port is not None:
        raise UsageError("--port: the simulator serves a pseudo-terminal or TCP; use --pty/--tcp")
    try:
        config = SimConfig()
        if args.config is not None:
            # A rov.toml serves both: its board tables are for the real robot only.
            data = read_toml(args.config)
            tables = {name: table for name, table in data.items() if name not in _BOARD_TABLES}
            config = sim_config_from_mapping(tables, args.config)
    except ConfigError as error:
        raise InputError(str(error)) from None
    if args.watchdog is not None:
        controller = dataclasses.replace(config.controller, watchdog_s=args.watchdog)
        config = dataclasses.replace(config, controller=controller)
    server = SimServer(config)
    try:
        endpoints = _open_pty_and_tcp(server, args, address)
        say_ready(f"rovlink controller ready: board sim, {', '.join(endpoints)}; Ctrl-C stops")
        server.serve(signals.stopping.is_set)
    finally:
        server.close()
    signals.say_stopped("rovlink controller")
    return 0


def _configure_logging() -> None:
    """INFO and above to stderr (journald under systemd, which adds its own timestamps)."""
    import logging  # noqa: PLC0415
    import os  # noqa: PLC0415

    under_journald = "JOURNAL_STREAM" in os.environ
    layout = "%(levelname)s %(name)s: %(message)s"
    logging.basicConfig(
        level=logging.INFO, format=layout if under_journald else "%(asctime)s " + layout
    )
