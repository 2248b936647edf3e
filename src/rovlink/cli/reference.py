"""Print the command reference (Markdown) generated from the command table, as in
docs/commands.md."""

from __future__ import annotations

import argparse
import sys

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink reference > docs/commands.md    the page of the docs, generated again
  rovlink reference | less"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``reference`` takes no arguments."""


def run(args: argparse.Namespace) -> int:
    """Print the reference."""
    from rovlink.protocol.reference import command_reference_markdown  # noqa: PLC0415

    # Bytes: the page is UTF-8 (docs/commands.md), whatever the locale's encoding would make it.
    sys.stdout.flush()
    sys.stdout.buffer.write(command_reference_markdown().encode("utf-8"))
    sys.stdout.buffer.flush()
    return 0
