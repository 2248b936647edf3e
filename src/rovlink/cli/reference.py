"""``rovlink reference``: print the command reference generated from the command table."""

from __future__ import annotations

import typer

from rovlink.protocol.reference import command_reference_markdown

__all__ = ["register"]


def register(app: typer.Typer) -> None:
    """Add ``reference`` to the command line."""

    @app.command()
    def reference() -> None:
        """Print the command reference (Markdown), as in docs/commands.md."""
        typer.echo(command_reference_markdown(), nl=False)
