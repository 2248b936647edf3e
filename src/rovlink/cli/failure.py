"""How a command reports that it cannot go on: one line on stderr and an exit status."""

from __future__ import annotations

__all__ = ["CommandError", "UsageError"]


class UsageError(Exception):
    """The command line was wrong (exit status 2, with the command's usage line).

    Raised for what argparse cannot check itself, e.g. a command text that does not parse.
    """


class CommandError(Exception):
    """The command ran and failed (exit status 1); the message is the whole story, one line.

    >>> str(CommandError("cannot open /dev/ttyUSB9: No such file or directory"))
    'cannot open /dev/ttyUSB9: No such file or directory'
    """
