"""``rovlink sim``: a simulated controller on a pseudo-terminal and/or a TCP port."""

from __future__ import annotations

import dataclasses
import signal
import threading
from pathlib import Path
from types import FrameType
from typing import Annotated

import typer

from rovlink.controller import ConfigError
from rovlink.sim.robot import SimConfig, load_sim_config
from rovlink.sim.server import SimServer, parse_tcp_address

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    """Add ``sim`` to the command line."""

    @app.command()
    def sim(
        *,
        tcp: Annotated[
            str | None,
            typer.Option(
                "--tcp", metavar="[HOST:]PORT",
                help="Listen on TCP (host 127.0.0.1 unless given); one client at a time.",
            ),
        ] = None,
        pty: Annotated[
            bool,
            typer.Option("--pty", help="Open a pseudo-terminal (the default without --tcp)."),
        ] = False,
        baud: Annotated[
            int | None,
            typer.Option("--baud", "--baudrate", min=1,
                         help="Pace the byte stream at this rate, 8N1."),
        ] = None,
        config: Annotated[
            Path | None,
            typer.Option(
                "--config", exists=True, dir_okay=False, readable=True,
                help="TOML file: controller tables, \\[vehicle], \\[sensors].",
            ),
        ] = None,
        leak_at: Annotated[
            float | None,
            typer.Option(
                "--leak-at", metavar="SECONDS", min=0.0,
                help="Inject a 100 ms leak pulse at this simulated time.",
            ),
        ] = None,
        seed: Annotated[
            int | None, typer.Option("--seed", help="Seed for reproducible noise.")
        ] = None,
        speed: Annotated[
            float,
            typer.Option(
                "--speed", min=0.0,
                help="Simulated seconds per wall second; 0 runs as fast as the CPU allows.",
            ),
        ] = 1.0,
        watchdog: Annotated[
            float | None,
            typer.Option(
                "--watchdog", metavar="SECONDS", min=0.0,
                help="Link-loss failsafe timeout (default from the config, 2 s); 0 turns it "
                "off, e.g. to type commands by hand.",
            ),
        ] = None,
    ) -> None:
        """Serve a simulated controller; open the printed port in any terminal program."""
        address = None
        if tcp is not None:
            try:
                address = parse_tcp_address(tcp)
            except ValueError as error:
                raise typer.BadParameter(str(error), param_hint="--tcp") from None
        try:
            robot_config = load_sim_config(config) if config is not None else SimConfig()
            if watchdog is not None:
                robot_config = dataclasses.replace(
                    robot_config,
                    controller=dataclasses.replace(robot_config.controller, watchdog_s=watchdog),
                )
        except ConfigError as error:  # the file's content, not the usage: one line, no box
            typer.echo(f"rovlink sim: {error}", err=True)
            raise typer.Exit(2) from None

        server = SimServer(robot_config, seed=seed, baud=baud, speed=speed)
        if leak_at is not None:
            server.robot.inject_leak(at_s=leak_at)
        try:
            endpoints = []
            if pty or address is None:
                endpoints.append(f"pty {server.open_pty()}")
            if address is not None:
                try:
                    host, port = server.listen_tcp(*address)
                except OSError as error:
                    typer.echo(f"rovlink sim: cannot listen on {tcp}: {error.strerror}", err=True)
                    raise typer.Exit(1) from None
                endpoints.append(f"tcp {host}:{port}")
            stop = _stop_on_signals()
            pacing = f"{baud} baud" if baud else "unpaced"
            typer.echo(
                f"rovlink sim ready: {', '.join(endpoints)} "
                f"(seed {server.robot.seed}, {pacing}); Ctrl-C stops"
            )
            server.serve(stop.is_set)
        finally:
            server.close()
        typer.echo("rovlink sim stopped", err=True)


def _stop_on_signals() -> threading.Event:
    """An event set by Ctrl-C or SIGTERM; the server loop sees it within 50 ms."""
    stop = threading.Event()

    def handle(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handle)
    signal.signal(signal.SIGTERM, handle)
    return stop
