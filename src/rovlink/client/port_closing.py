"""Closing a port with a bound: a close that hangs never holds the program.

Closing a serial device waits in the kernel until the bytes written have left (up to the
terminal's ``closing_wait``, 30 s by default) and a USB adapter whose driver is stuck can hang it
for good; pyserial's ``rfc2217://`` waits up to 7 s for its reader thread and then sleeps 0.3 s.
Done in the caller's thread, that held ``close()`` — and an asyncio client's event loop — for as
long. So a port is closed in a thread of its own, waited for at most :data:`CLOSE_TIMEOUT_S`,
and a close still under way then is reported (a warning naming the port) and left to end in the
background: the program goes on, and the port is free again once the close ends.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from rovlink.client.links import Link, SerialFdLink, SocketLink
from rovlink.logs import get_logger

__all__ = ["CLOSE_TIMEOUT_S", "PortClosing", "close_within"]

#: How long closing a port is waited for before it is left to end in the background.
CLOSE_TIMEOUT_S = 2.0

logger = get_logger("rovlink.client")


class PortClosing:
    """The close of one link, under way in a thread of its own.

    Example::

        closing = PortClosing(link)
        if not closing.wait(2.0):
            print("still closing")
    """

    def __init__(self, link: Link, *, then: Callable[[], None] | None = None) -> None:
        """Start closing ``link``; ``then`` is called in the closing thread once it has ended
        (an event loop's wake-up).

        Example::

            closing = PortClosing(link, then=lambda: print("closed"))
        """
        self._link = link
        self._then = then
        self._error: Exception | None = None
        #: Set once the link's ``close()`` has returned (or raised).
        self.done = threading.Event()
        threading.Thread(
            target=self._close, name=f"rovlink close ({link.description})", daemon=True
        ).start()

    def _close(self) -> None:
        try:
            self._link.close()
        except Exception as error:  # (handed to the waiting thread: see wait)
            self._error = error
        finally:
            self.done.set()
            if self._then is not None:
                self._then()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait at most ``timeout_s`` (``None``: :data:`CLOSE_TIMEOUT_S`) for the close; True
        once it ended, raising what it raised. False, with a warning, if it is still under way.

        Example::

            PortClosing(link).wait()
        """
        if timeout_s is None:
            timeout_s = CLOSE_TIMEOUT_S
        if not self.done.wait(timeout_s):
            self.report(timeout_s)
            return False
        return self.ended()

    def ended(self) -> bool:
        """Whether the close has ended (raising what it raised).

        Example::

            if not closing.ended():
                closing.report(2.0)
        """
        if not self.done.is_set():
            return False
        if self._error is not None:
            raise self._error
        return True

    def report(self, waited_s: float) -> None:
        """Say that the port has not closed after ``waited_s`` seconds (a warning).

        Example::

            closing.report(2.0)
        """
        logger.warning(
            "%s: the port did not close within %g s (%s); left to close in the background",
            self._link.description,
            waited_s,
            _why_a_close_hangs(self._link),
        )


def _why_a_close_hangs(link: Link) -> str:
    """What usually holds up the close of a link of ``link``'s kind, for the warning.

    >>> _why_a_close_hangs(SocketLink.__new__(SocketLink))
    'a network port that does not answer'
    """
    if isinstance(link, SerialFdLink):
        return "a serial adapter whose driver hangs"
    if isinstance(link, SocketLink):
        return "a network port that does not answer"
    if getattr(link, "writes_may_wait", True) is False:  # an in-process port (sim://)
        return "the in-process port is busy"
    return "the port's close is waiting for its device or its network peer"


def close_within(link: Link, timeout_s: float | None = None) -> bool:
    """Close ``link``, waiting at most ``timeout_s`` (``None``: :data:`CLOSE_TIMEOUT_S`); False,
    with a warning, if the close is still under way then (it ends in the background).

    >>> from rovlink.client.links import open_link
    >>> from rovlink.client.url import parse_url
    >>> close_within(open_link(parse_url("loop://")))
    True
    """
    return PortClosing(link).wait(timeout_s)
