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

__all__ = ["get_logger"]

logging.getLogger("rovlink").addHandler(logging.NullHandler())


def get_logger(name: str) -> logging.Logger:
    """The logger ``name`` (under ``rovlink``), with the library's policy in force."""
    if name != "rovlink" and not name.startswith("rovlink."):
        raise ValueError(f"rovlink's loggers are named rovlink.*, got {name!r}")
    return logging.getLogger(name)
