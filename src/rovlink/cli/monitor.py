"""``rovlink monitor [URL]``: a live terminal dashboard, on the simulator by default."""

from __future__ import annotations

from collections.abc import Awaitable
from typing import TYPE_CHECKING

import typer

from rovlink.cli.link_options import (
    DEFAULT_URL,
    AlgorithmOption,
    BaudrateOption,
    ChecksumOption,
    RetriesOption,
    TimeoutOption,
    UrlArgument,
)
from rovlink.protocol import DEFAULT_ALGORITHM

if TYPE_CHECKING:
    from rovlink.aio import AsyncClient
    from rovlink.client.options import StrayCallback
    from rovlink.monitor.app import MonitorApp

__all__ = ["build_app", "register"]


def build_app(url: str, *, rate_hz: float = 5.0, checksum: bool = False,
              algorithm: str = "crc8", baudrate: int | None = None, timeout_s: float = 0.5,
              retries: int = 2) -> MonitorApp:
    """The monitor for ``url``, connecting when it starts (the URL is checked now)."""
    import rovlink.aio  # noqa: PLC0415 - keep the driver and textual off other commands
    from rovlink.client import ClientOptions, parse_url  # noqa: PLC0415
    from rovlink.monitor.app import MonitorApp  # noqa: PLC0415

    parse_url(url, baudrate)
    ClientOptions(timeout_s, retries, checksum, algorithm)  # checks the options now

    def connect(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
        return rovlink.aio.connect(url, timeout=timeout_s, retries=retries, checksum=checksum,
                                   algorithm=algorithm, baudrate=baudrate, on_stray=on_stray)

    return MonitorApp(connect, description=url, rate_hz=rate_hz, algorithm=algorithm)


def register(app: typer.Typer) -> None:
    """Add ``monitor`` to the command line."""

    @app.command()
    def monitor(  # noqa: PLR0917 - Typer reads the options from the parameters
        url: UrlArgument = DEFAULT_URL,
        rate_hz: float = typer.Option(5.0, "--rate", help="Sensor polls per second.", min=0.1,
                                      max=100),
        checksum: ChecksumOption = False,
        algorithm: AlgorithmOption = DEFAULT_ALGORITHM,
        baudrate: BaudrateOption = None,
        timeout_s: TimeoutOption = 0.5,
        retries: RetriesOption = 2,
    ) -> None:
        """Live depth, attitude, leak alarm, link health and a depth chart; keys drive the robot.

        space stops, s starts, arrows set direction and power, PgUp/PgDn the depth target,
        o/c the claw, r resets the leak latch, q quits (sending #stop! unless locked).
        Try a leak: rovlink monitor 'sim://?leak_at=5'
        """
        try:
            monitor_app = build_app(url, rate_hz=rate_hz, checksum=checksum,
                                    algorithm=algorithm, baudrate=baudrate,
                                    timeout_s=timeout_s, retries=retries)
        except ValueError as error:
            raise typer.BadParameter(str(error)) from None
        monitor_app.run()
