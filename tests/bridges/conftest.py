"""Fixtures shared by the bridges' tests: the command line run in-process."""

from __future__ import annotations

from tests.cli.conftest import run_cli

__all__ = ["run_cli"]
