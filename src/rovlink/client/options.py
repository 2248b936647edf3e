"""Connection options shared by both clients, checked before any port is opened."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

from rovlink.client.events import EventCallback, check_not_async
from rovlink.protocol import ALGORITHMS, Event

__all__ = [
    "DEFAULT_BOOT_TIMEOUT_S",
    "DEFAULT_MOTION_TIMEOUT_S",
    "ClientOptions",
    "StrayCallback",
    "connect_options",
]

#: How long ``connect`` waits for the controller to answer: an Arduino-class board resets when its
#: port opens and ignores input for up to 2 s while it boots (P21).
DEFAULT_BOOT_TIMEOUT_S = 3.0
#: How long a motion command (``move``, ``set_vertical_thrust``) lasts unless renewed (P23): the
#: controller's own link-loss watchdog default (P17), so the keep-alive never lets a program that
#: went silent keep the robot moving longer than the controller itself would.
DEFAULT_MOTION_TIMEOUT_S = 2.0
#: Upper bounds that catch a typo (``timeout=1e10``) rather than limit a real use.
MAX_TIMEOUT_S = 3600.0
MAX_RETRIES = 100
#: A keep-alive more often than this is a flood of queries, not a keep-alive (the controller's
#: link-loss watchdog waits 2 s by default, P17).
MIN_KEEPALIVE_S = 0.01

#: Called with every event that answered no query: debug text, noise, dropped or stray frames.
StrayCallback = Callable[[Event], None]


@dataclass(frozen=True, slots=True)
class ClientOptions:
    """The settings of one connection, checked once, shared by both clients and the tools.

    ``timeout_s`` per query attempt, ``retries`` extra attempts of a query, the checksum
    mode and algorithm to put the controller in, ``keepalive_s`` of idle link before a
    keep-alive query (``None`` or 0: never), ``boot_timeout_s`` to wait on connect for the
    controller to answer (``None``: do not wait), ``motion_timeout_s`` after which an unrenewed
    motion command is expired with zero thrust (``None``: never), ``on_stray`` for what
    answered no query, ``on_event`` for every event of the connection, ``reconnect`` to
    reopen a lost link (a serial adapter unplugged and plugged back) with backoff, and
    ``stop_on_close`` to send ``#stop!`` on ``close()`` when the program has moved or unlocked
    the robot since its last stop (``False``: leave the robot as it is, to the next program).

    >>> ClientOptions(timeout_s=0).timeout_s
    Traceback (most recent call last):
    ...
    ValueError: timeout must be a positive number of seconds up to 3600, got 0
    """

    timeout_s: float = 0.5
    retries: int = 2
    checksum: bool = False
    algorithm: str = "crc8"
    keepalive_s: float | None = 1.0
    on_stray: StrayCallback | None = None
    boot_timeout_s: float | None = DEFAULT_BOOT_TIMEOUT_S
    motion_timeout_s: float | None = DEFAULT_MOTION_TIMEOUT_S
    on_event: EventCallback | None = None
    reconnect: bool = False
    stop_on_close: bool = True

    def __post_init__(self) -> None:
        _check_seconds("timeout", self.timeout_s, optional=False)
        retries_text = f"retries must be an integer from 0 to {MAX_RETRIES}, got {self.retries!r}"
        if isinstance(self.retries, bool) or not isinstance(self.retries, int):
            raise TypeError(retries_text)
        if not 0 <= self.retries <= MAX_RETRIES:
            raise ValueError(retries_text)
        _check_seconds("boot_timeout", self.boot_timeout_s, optional=True)
        _check_seconds("motion_timeout", self.motion_timeout_s, optional=True)
        if not isinstance(self.reconnect, bool):
            raise TypeError(f"reconnect must be True or False, got {self.reconnect!r}")
        if not isinstance(self.stop_on_close, bool):
            raise TypeError(f"stop_on_close must be True or False, got {self.stop_on_close!r}")
        if not isinstance(self.checksum, bool):
            raise TypeError(f"checksum must be True or False, got {self.checksum!r}")
        if self.algorithm not in ALGORITHMS:
            known = ", ".join(ALGORITHMS)
            raise ValueError(f"algorithm must be one of {known}, got {self.algorithm!r}")
        keepalive = self.keepalive_s
        keepalive_text = (
            f"keepalive must be seconds from {MIN_KEEPALIVE_S:g} to {MAX_TIMEOUT_S:g}, or 0 "
            f"or None for never, got {keepalive!r}"
        )
        if keepalive is not None:
            if isinstance(keepalive, bool) or not isinstance(keepalive, int | float):
                raise TypeError(keepalive_text)
            if not (keepalive == 0 or MIN_KEEPALIVE_S <= keepalive <= MAX_TIMEOUT_S):
                raise ValueError(keepalive_text)
        for name in ("on_stray", "on_event"):
            callback = getattr(self, name)
            if callback is not None and not callable(callback):
                raise TypeError(f"{name} must be callable, got {callback!r}")
            check_not_async(name, callback)


def _check_seconds(name: str, value: object, *, optional: bool) -> None:
    """A positive number of seconds up to an hour (or ``None`` where that means "never");
    TypeError for what is no number, ValueError for a number out of range."""
    if value is None and optional:
        return
    never = " or None" if optional else ""
    text = (
        f"{name} must be a positive number of seconds up to {MAX_TIMEOUT_S:g}{never}, got {value!r}"
    )
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(text)
    if not 0 < value <= MAX_TIMEOUT_S:
        raise ValueError(text)


#: ``connect``'s keywords that are settings, with the :class:`ClientOptions` field each sets.
_KEYWORD_FIELDS = {
    "timeout": "timeout_s",
    "retries": "retries",
    "checksum": "checksum",
    "algorithm": "algorithm",
    "keepalive": "keepalive_s",
    "on_stray": "on_stray",
    "boot_timeout": "boot_timeout_s",
    "motion_timeout": "motion_timeout_s",
    "on_event": "on_event",
    "reconnect": "reconnect",
    "stop_on_close": "stop_on_close",
}


def connect_options(options: ClientOptions | None, **keywords: Any) -> ClientOptions:
    """The settings of ``connect(url, ..., options=...)``: ``options``, or the keywords.

    Both at once is a TypeError naming the keywords that differ from their defaults: they would
    have been dropped without a word (``timeout=0.1`` beside an ``options`` of 0.5 s).

    >>> connect_options(None, timeout=0.2).timeout_s
    0.2
    >>> connect_options(ClientOptions(retries=0), timeout=0.2)  # doctest: +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    TypeError: connect: timeout=0.2 given with options=: give every setting in the ClientOptions
    (timeout_s=0.2), or none of them
    """
    if options is None:
        return ClientOptions(**{_KEYWORD_FIELDS[name]: value for name, value in keywords.items()})
    if not isinstance(options, ClientOptions):
        raise TypeError(f"options must be a rovlink.client.ClientOptions, got {options!r}")
    defaults = {field.name: field.default for field in fields(ClientOptions)}
    given = {
        name: value
        for name, value in keywords.items()
        if value is not defaults[_KEYWORD_FIELDS[name]] and value != defaults[_KEYWORD_FIELDS[name]]
    }
    if given:
        as_keywords = ", ".join(f"{name}={value!r}" for name, value in given.items())
        as_fields = ", ".join(f"{_KEYWORD_FIELDS[name]}={value!r}" for name, value in given.items())
        raise TypeError(
            f"connect: {as_keywords} given with options=: give every setting in the "
            f"ClientOptions ({as_fields}), or none of them"
        )
    return options
