"""How a command reports that it cannot go on: one line on stderr and an exit status."""

from __future__ import annotations

__all__ = ["CommandError", "InputError", "UsageError"]


class UsageError(Exception):
    """The command line was wrong (exit status 2, with the command's usage line).

    Raised for what argparse cannot check itself, e.g. a command text that does not parse.
    """


class CommandError(Exception):
    """The command ran and failed (exit status 1); the message is the whole story, one line.

    >>> str(CommandError("cannot open /dev/ttyUSB9: No such file or directory"))
    'cannot open /dev/ttyUSB9: No such file or directory'
    """

    exit_status = 1


class InputError(CommandError):
    """A file the command was given is unusable (exit status 2, like a usage error, but one
    line: the file's content, not the command line, is what to fix).

    >>> InputError("robot.toml: not UTF-8 text").exit_status
    2
    """

    exit_status = 2
