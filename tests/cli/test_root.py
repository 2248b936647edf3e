"""The ``rovlink`` command itself: its version and the list of commands."""

from __future__ import annotations

from typer.testing import CliRunner

import rovlink
from rovlink.cli import app

runner = CliRunner()


def test_version() -> None:
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0
    assert result.output.strip() == f"rovlink {rovlink.__version__}"


def test_help_lists_every_command() -> None:
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0
    for name in ("decode", "reference", "sim", "send", "demo", "console", "monitor"):
        assert f" {name} " in result.output
