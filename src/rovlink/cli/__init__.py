"""The ``rovlink`` command line: one module per command, each adding itself to the Typer app."""

from __future__ import annotations

import importlib
import logging

import typer

import rovlink

__all__ = ["app", "main"]

app = typer.Typer(
    name="rovlink",
    help="Drive an underwater robot's low-level controller over its serial command protocol.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

# Each module defines ``register(app)``. Heavy imports stay inside the commands, so that
# ``rovlink decode`` does not pay for the terminal user interfaces.
_COMMAND_MODULES = ("decode", "reference", "sim", "send", "demo", "console", "monitor")

for _name in _COMMAND_MODULES:
    importlib.import_module(f"rovlink.cli.{_name}").register(app)


def _print_version(value: bool) -> None:
    if value:
        typer.echo(f"rovlink {rovlink.__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    verbose: bool = typer.Option(False, "--verbose", "-v", help="Log debug details to stderr."),
    version: bool = typer.Option(
        False, "--version", is_eager=True, callback=_print_version, help="Print the version."
    ),
) -> None:
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING,
        format="%(asctime)s %(name)s %(levelname)s: %(message)s",
    )


def main() -> None:
    """Entry point of the ``rovlink`` console script."""
    app()
