"""The controller's link as ``rovlink record`` holds it: lost, it is reopened at the same URL
with the clients' backoff (0.1 s, doubling to 2 s; :mod:`rovlink.client.reconnection`), so that
one USB-serial adapter dropout neither ends the recording nor disconnects a tap's program.

Nothing is written on a link that is down: what a tap's program sends meanwhile is dropped (it
gets no replies, and its own timeouts and reset handling, P21, take over), never queued to run
after the return. On the return, :attr:`ReopeningLink.on_return` writes first, before any byte of
the program's (the tap's ``#stop!``).
"""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable

from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import Link
from rovlink.client.reconnection import (
    FailedAttempts,
    reconnect_delays_s,
    reconnecting_failed,
)

__all__ = ["ReopeningLink"]

logger = logging.getLogger(__name__)


class ReopeningLink:
    """``link``, reopened with ``reopen`` when lost, until ``stopping`` is set.

    ``on_change(state, detail)`` is told ``lost`` and ``reconnected`` (the states of the
    clients' :class:`~rovlink.client.events.LinkState`). ``may_reopen()``, asked as the link is
    lost, says whether to reopen it; when it says no (``--exit-on-loss``, or a controller that
    closed before a frame came), :meth:`read_available` raises the
    :class:`~rovlink.client.errors.ConnectionLostError`, as a plain link does.
    """

    def __init__(
        self,
        link: Link,
        reopen: Callable[[], Link],
        *,
        stopping: threading.Event,
        on_change: Callable[[str, str], None],
        may_reopen: Callable[[], bool],
    ) -> None:
        self.description = link.description
        #: Written on the reopened link before anything else (the link's write lock held).
        self.on_return: Callable[[Link], None] | None = None
        self._link: Link | None = link
        self._reopen = reopen
        self._stopping = stopping
        self._on_change = on_change
        self._may_reopen = may_reopen
        self._lock = threading.Lock()  # the current link: swapped and written under it
        # The backoff goes on across reopened links that close before a frame comes on them
        # (a controller busy with another client says so and closes): no attempt every 0.1 s.
        self._delays_s = reconnect_delays_s()
        self._heard = True  # a frame came on the current link (on the first: may_reopen)

    def read_available(self, timeout_s: float) -> bytes:
        """What came within ``timeout_s``; a lost link is reopened here (this blocks until it
        is, or ``stopping`` is set) and gives ``b""``."""
        link = self._link
        if link is None:
            self._reconnect()
            return b""
        try:
            data = link.read_available(timeout_s)
        except ConnectionLostError as error:
            self._lose(link)
            if not self._may_reopen():
                raise
            self._on_change("lost", f"{error}; reconnecting")
            logger.warning("%s; reconnecting", error)
            self._reconnect()
            return b""
        if not self._heard and b"!" in data:  # (the end of a frame; text never holds one, P5)
            self._heard = True
            self._delays_s = reconnect_delays_s()
        return data

    def write(self, data: bytes, *, before: Callable[[], None] | None = None) -> bool:
        """Write ``data`` if the link is up; whether it was (bytes for a link that is down are
        dropped: a loss seen here is left to the reader to announce and mend). ``before`` is
        called just before, only if the link is up, under the lock that :attr:`on_return`
        writes under: what it records is in the wire's order."""
        with self._lock:
            link = self._link
            if link is None:
                return False
            if before is not None:
                before()
            try:
                link.write(data)
            except ConnectionLostError as error:
                logger.debug("%s: a write found the link lost: %s", self.description, error)
                self._link = None
                with contextlib.suppress(Exception):
                    link.close()
                return False
            return True

    def close(self) -> None:
        """Close the current link, if any."""
        with self._lock:
            link, self._link = self._link, None
        if link is not None:
            link.close()

    def _lose(self, link: Link) -> None:
        with self._lock:
            if self._link is link:
                self._link = None
        with contextlib.suppress(Exception):
            link.close()

    def _reconnect(self) -> None:
        """Reopen with the clients' backoff until it opens or ``stopping`` is set."""
        if not self._heard:  # (lost before a frame came on it: as a failed attempt)
            self._stopping.wait(next(self._delays_s))
        attempts = 0
        failed = FailedAttempts(logger)
        while not self._stopping.is_set():
            attempts += 1
            try:
                link = self._reopen()
            except (OSError, ValueError) as error:  # ConnectionError too: not there yet
                failed.note(attempts, error)
                self._stopping.wait(next(self._delays_s))
                continue
            except Exception as error:  # a bug in the opener: no retry can help
                raise reconnecting_failed(self.description, error, logger) from error
            plural = "" if attempts == 1 else "s"
            detail = f"{link.description} after {attempts} attempt{plural}"
            with self._lock:
                self._link = link
                self._heard = False
                self._on_change("reconnected", detail)  # (before what on_return writes)
                try:
                    if self.on_return is not None:
                        self.on_return(link)
                except ConnectionLostError as error:  # lost again at once: try again
                    self._link = None
                    link.close()
                    self._on_change("lost", f"{error}; reconnecting")
                    lost_again = True
                else:
                    lost_again = False
            if lost_again:  # (waited for with the lock free: writes find the link down)
                self._stopping.wait(next(self._delays_s))
                continue
            logger.warning("%s: reconnected", detail)
            return
