"""Serve a simulated controller on a pseudo-terminal and/or a TCP port: open the printed port
in any terminal program (picocom, miniterm, socat) or give it to rovlink as a URL."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from rovlink.cli.failure import CommandError, InputError, UsageError, reason
from rovlink.cli.interrupt import ServingSignals, say_ready
from rovlink.cli.link_options import baud_rate, bounded_float, file_name, log_warnings, seconds
from rovlink.cli.tcp_endpoint import listen_address, tcp_endpoint

if TYPE_CHECKING:
    from rovlink.sim.robot import SimConfig

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink sim                          a pseudo-terminal; its path is printed
  rovlink sim --tcp 5760 --seed 1      TCP on 127.0.0.1:5760, reproducible noise
  rovlink sim --pty --tcp 0.0.0.0:5760 --baud 9600 --watchdog 0"""

_MAX_SIM_SECONDS = 1e9  # beyond any simulated run


def _sim_seconds(text: str) -> float:
    return seconds(text, maximum=_MAX_SIM_SECONDS)


def _speed(text: str) -> float:
    return bounded_float(text, 0.0, 1e6)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``sim``'s options."""
    parser.add_argument(
        "--tcp",
        metavar="[HOST:]PORT",
        help="listen on TCP (host 127.0.0.1 unless given); one client at a time",
    )
    parser.add_argument(
        "--pty", action="store_true", help="open a pseudo-terminal (the default without --tcp)"
    )
    parser.add_argument(
        "--baud",
        "--baudrate",
        dest="baud",
        type=baud_rate,
        metavar="BAUD",
        help="pace the byte stream at this rate, 8N1 (default: unpaced)",
    )
    parser.add_argument(
        "--config",
        type=file_name,
        metavar="FILE",
        help="TOML file: controller tables, [vehicle], [sensors]",
    )
    parser.add_argument(
        "--leak-at",
        dest="leak_at",
        type=_sim_seconds,
        metavar="SECONDS",
        help="inject a 100 ms leak pulse at this simulated time",
    )
    parser.add_argument(
        "--preset",
        choices=("light", "standard", "heavy"),
        help="a simulated vehicle of rovlink.sim.presets (heave waves on) in place of [vehicle]",
    )
    parser.add_argument("--seed", type=int, help="seed for reproducible noise (default: random)")
    parser.add_argument(
        "--speed",
        type=_speed,
        default=1.0,
        metavar="FACTOR",
        help="simulated seconds per wall second; 0 runs as fast as the CPU "
        "allows (default: %(default)s)",
    )
    parser.add_argument(
        "--watchdog",
        type=_sim_seconds,
        metavar="SECONDS",
        help="link-loss failsafe timeout (default: from the config, 2 s); 0 "
        "turns it off, e.g. to type commands by hand",
    )


def _robot_config(args: argparse.Namespace) -> SimConfig:
    import dataclasses  # noqa: PLC0415

    from rovlink.controller import ConfigError  # noqa: PLC0415
    from rovlink.sim.robot import SimConfig, load_sim_config  # noqa: PLC0415

    try:
        robot_config = load_sim_config(args.config) if args.config is not None else SimConfig()
    except ConfigError as error:  # the file's content, not the command line: no usage text
        raise InputError(str(error)) from None
    if getattr(args, "preset", None) is not None:
        from rovlink.sim.presets import preset_config  # noqa: PLC0415

        robot_config = preset_config(args.preset, robot_config)
    if args.watchdog is not None:
        robot_config = dataclasses.replace(
            robot_config,
            controller=dataclasses.replace(robot_config.controller, watchdog_s=args.watchdog),
        )
    return robot_config


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C or SIGTERM."""
    from rovlink.sim.server import SimServer, parse_tcp_address  # noqa: PLC0415

    address = None
    if args.tcp is not None:
        try:
            address = parse_tcp_address(args.tcp)
        except ValueError as error:
            raise UsageError(f"--tcp: {error}") from None
    server = SimServer(_robot_config(args), seed=args.seed, baud=args.baud, speed=args.speed)
    if args.leak_at is not None:
        server.robot.inject_leak(at_s=args.leak_at)
    signals: ServingSignals | None = None
    # A simulation behind the wall clock, a failsafe, a leak, a listener other computers reach:
    # a server's news, on stderr.
    log_warnings()
    try:
        endpoints = []
        if args.pty or address is None:
            endpoints.append(f"pty {server.open_pty()}")
        if address is not None:
            try:
                host, port = server.listen_tcp(*address)
            except OSError as error:
                where = listen_address(*address)
                raise CommandError(f"cannot listen on {where}: {reason(error)}") from None
            endpoints.append(tcp_endpoint(host, port, "rovlink.sim"))
        signals = ServingSignals()
        pacing = f"{args.baud} baud" if args.baud else "unpaced"
        say_ready(
            f"rovlink sim ready: {', '.join(endpoints)} "
            f"(seed {server.robot.seed}, {pacing}); Ctrl-C stops"
        )
        server.serve(signals.stopping.is_set)
    finally:
        server.close()
        if signals is not None:
            signals.restore()
    if signals is not None:
        signals.say_stopped("rovlink sim")  # (a closed terminal, SIGHUP, takes no line)
        signals.finish()  # (Ctrl-C: status 130; SIGTERM, SIGHUP: a service stopped, 0)
    return 0
