"""The rich console of the commands that print tables (``demo``, ``check``, ``fleet``).

Imported only by those commands as they run: rich is not on the path of ``--help``.
"""

from __future__ import annotations

import errno

from rich.console import Console

__all__ = ["TableConsole"]


class TableConsole(Console):
    """A rich console whose closed output (``| head``) ends the command as ``print``'s does.

    Rich's own console exits at once with status 1 and nothing said, past the command's
    handling: a reader that stops early is no error (status 0), and a command that may have
    moved the robot sends ``#stop!`` first (:func:`rovlink.cli.main`).
    """

    def on_broken_pipe(self) -> None:
        """Raise the closed output as the :class:`BrokenPipeError` it is."""
        raise BrokenPipeError(errno.EPIPE, "Broken pipe")
