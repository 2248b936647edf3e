"""``rovlink console [URL]``: an interactive console for the robot, on the simulator by default."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable
from pathlib import Path
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

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    """Add ``console`` to the command line."""

    @app.command()
    def console(  # noqa: PLR0917 - Typer reads the options from the parameters
        url: UrlArgument = DEFAULT_URL,
        checksum: ChecksumOption = False,
        algorithm: AlgorithmOption = DEFAULT_ALGORITHM,
        baudrate: BaudrateOption = None,
        timeout_s: TimeoutOption = 0.5,
        retries: RetriesOption = 2,
        history: Path | None = typer.Option(
            None, "--history", help="History file (default: in the user's state directory)."
        ),
    ) -> None:
        """Type commands (qd, th 270 25, mvs -50, #qd!) and see the replies; Ctrl-X stops.

        Tab completes names and shows each argument's range; 'help' lists every command.
        """
        import rovlink.aio  # noqa: PLC0415 - keep the driver and prompt_toolkit off other commands
        from rovlink.client import parse_url  # noqa: PLC0415
        from rovlink.client.options import StrayCallback  # noqa: PLC0415
        from rovlink.console.app import run_console  # noqa: PLC0415
        from rovlink.console.history import default_history_path  # noqa: PLC0415

        def connect(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
            return rovlink.aio.connect(
                url, timeout=timeout_s, retries=retries, checksum=checksum,
                algorithm=algorithm, baudrate=baudrate, on_stray=on_stray,
            )

        try:
            parse_url(url, baudrate)
        except ValueError as error:
            raise typer.BadParameter(str(error), param_hint="URL") from None
        try:
            asyncio.run(run_console(connect, algorithm=algorithm,
                                    history_path=history or default_history_path()))
        except ValueError as error:
            raise typer.BadParameter(str(error)) from None
        except ConnectionError as error:
            typer.echo(f"error: {error}", err=True)
            raise typer.Exit(1) from None
