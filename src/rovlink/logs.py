"""The library's logging policy: every logger is under ``rovlink`` and silent by default.

A library logs, and the program that uses it decides where that goes. Without a handler of its
own, Python's last-resort handler would print every warning of a program that configured no
logging on its stderr; the ``NullHandler`` on ``rovlink`` keeps them for whoever configures
logging. (It is installed here, where logging is imported anyway, rather than in the package's
``__init__``: ``rovlink --version`` must not pay for importing ``logging``.)

>>> get_logger("rovlink.client").name
'rovlink.client'
"""

from __future__ import annotations

import logging
from collections.abc import Callable

__all__ = ["WarningsShownBy", "get_logger"]

logging.getLogger("rovlink").addHandler(logging.NullHandler())


def get_logger(name: str) -> logging.Logger:
    """The logger ``name`` (under ``rovlink``), with the library's policy in force."""
    if name != "rovlink" and not name.startswith("rovlink."):
        raise ValueError(f"rovlink's loggers are named rovlink.*, got {name!r}")
    return logging.getLogger(name)


class WarningsShownBy(logging.Handler):
    """While attached, the library's warnings and errors go to ``show(message, level)`` and
    nowhere else: for a tool that owns the terminal (a dashboard, a console's prompt), where a
    line written to stderr would land in the middle of its screen.

    >>> shown = []
    >>> warnings = WarningsShownBy(lambda message, level: shown.append(message))
    >>> warnings.attach(); get_logger("rovlink.client").warning("link lost"); warnings.detach()
    >>> shown
    ['link lost']
    """

    def __init__(self, show: Callable[[str, int], None]) -> None:
        super().__init__(logging.WARNING)
        self._show = show
        self._logger = logging.getLogger("rovlink")
        self._propagated = True

    def attach(self) -> None:
        """Take the library's warnings (until :meth:`detach`)."""
        self._propagated = self._logger.propagate
        self._logger.addHandler(self)
        self._logger.propagate = False

    def detach(self) -> None:
        """Let them go where they went before."""
        self._logger.removeHandler(self)
        self._logger.propagate = self._propagated

    def emit(self, record: logging.LogRecord) -> None:
        """Hand one record's message to ``show``."""
        self._show(record.getMessage(), record.levelno)
