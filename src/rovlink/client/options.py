"""Connection options shared by both clients, checked before any port is opened."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from rovlink.protocol import ALGORITHMS, Event

__all__ = ["ClientOptions", "StrayCallback"]

#: Called with every event that answered no query: debug text, noise, dropped or stray frames.
StrayCallback = Callable[[Event], None]


@dataclass(frozen=True, slots=True)
class ClientOptions:
    """``timeout_s`` per query attempt, ``retries`` extra attempts of a query, the checksum
    mode and algorithm to put the controller in, and ``keepalive_s`` of idle link before a
    keep-alive query (``None`` or 0: never).

    >>> ClientOptions(timeout_s=0).timeout_s
    Traceback (most recent call last):
    ...
    ValueError: timeout must be a positive number of seconds, got 0
    """

    timeout_s: float = 0.5
    retries: int = 2
    checksum: bool = False
    algorithm: str = "crc8"
    keepalive_s: float | None = 1.0
    on_stray: StrayCallback | None = None

    def __post_init__(self) -> None:
        if isinstance(self.timeout_s, bool) or not isinstance(self.timeout_s, int | float) \
                or not self.timeout_s > 0:
            raise ValueError(
                f"timeout must be a positive number of seconds, got {self.timeout_s!r}"
            )
        if isinstance(self.retries, bool) or not isinstance(self.retries, int) \
                or self.retries < 0:
            raise ValueError(f"retries must be an integer ≥ 0, got {self.retries!r}")
        if not isinstance(self.checksum, bool):
            raise TypeError(f"checksum must be True or False, got {self.checksum!r}")
        if self.algorithm not in ALGORITHMS:
            known = ", ".join(ALGORITHMS)
            raise ValueError(f"algorithm must be one of {known}, got {self.algorithm!r}")
        keepalive = self.keepalive_s
        if keepalive is not None and (isinstance(keepalive, bool)
                                      or not isinstance(keepalive, int | float)
                                      or keepalive < 0):
            raise ValueError(
                f"keepalive must be a number of seconds ≥ 0 or None, got {keepalive!r}"
            )
        if self.on_stray is not None and not callable(self.on_stray):
            raise TypeError(f"on_stray must be callable, got {self.on_stray!r}")

    @property
    def keepalive_enabled(self) -> bool:
        """Whether idle links get keep-alive queries.

        >>> ClientOptions(keepalive_s=None).keepalive_enabled
        False
        """
        return bool(self.keepalive_s)
