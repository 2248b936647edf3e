"""What the blocking and asyncio clients share when ``reconnect=True`` reopens a lost port.

The delays between attempts (0.1 s, doubling to 2 s: fast after a glitch, gentle on a port that
stays away), and the error that ends reconnecting for good when an attempt fails in a way no
retry can mend.

>>> delays = reconnect_delays_s()
>>> [next(delays) for _ in range(7)]
[0.1, 0.2, 0.4, 0.8, 1.6, 2.0, 2.0]
"""

from __future__ import annotations

import logging
from collections.abc import Iterator

from rovlink.client.errors import ConnectionLostError

__all__ = ["FailedAttempts", "reconnect_delays_s", "reconnecting_failed"]

_FIRST_DELAY_S = 0.1
_MAX_DELAY_S = 2.0


def reconnect_delays_s() -> Iterator[float]:
    """The wait after each failed attempt, in seconds: 0.1, doubling up to 2, for ever.

    >>> import itertools
    >>> list(itertools.islice(reconnect_delays_s(), 7))
    [0.1, 0.2, 0.4, 0.8, 1.6, 2.0, 2.0]
    """
    delay_s = _FIRST_DELAY_S
    while True:
        yield delay_s
        delay_s = min(delay_s * 2, _MAX_DELAY_S)


class FailedAttempts:
    """Says why reopening a port fails, once: the first failed attempt, and one that fails for
    another reason, is a warning; the same reason again goes to the debug log (a port away all
    day does not put a line in the log every 2 s).

    >>> import logging
    >>> failed = FailedAttempts(logging.getLogger("x"))
    >>> failed.note(1, OSError("cannot open /dev/ttyUSB0: No such file or directory"))
    >>> failed.said
    'cannot open /dev/ttyUSB0: No such file or directory'
    """

    def __init__(self, logger: logging.Logger) -> None:
        self._logger = logger
        #: The reason last said as a warning ("" before the first failure).
        self.said = ""

    def note(self, attempt: int, error: Exception) -> None:
        """Log failed attempt number ``attempt`` (from 1) and why.

        >>> failed = FailedAttempts(logging.getLogger("x"))
        >>> failed.note(1, OSError("cannot open /dev/ttyUSB0: permission denied"))
        >>> failed.note(2, OSError("cannot open /dev/ttyUSB0: permission denied"))  # (debug)
        >>> failed.said
        'cannot open /dev/ttyUSB0: permission denied'
        """
        reason = str(error)
        if reason == self.said:
            self._logger.debug("reconnect attempt %d: %s", attempt, reason)
            return
        self.said = reason
        self._logger.warning("reconnect attempt %d: %s; retrying", attempt, reason)


def reconnecting_failed(
    description: str, error: Exception, logger: logging.Logger
) -> ConnectionLostError:
    """Log, with its traceback, an attempt that failed with an error that is neither the
    port's nor the URL's (a bug in a ``reopen`` callable or a link scheme's opener), and return
    the error every call raises from then on: the link is lost for good, as without
    ``reconnect``, so that calls say why at once rather than wait for a link that will never
    come (the controller's link-loss failsafe, P17, stops the robot).

    >>> lost = reconnecting_failed("/dev/ttyUSB0", KeyError("baud"), logging.getLogger("x"))
    >>> str(lost)
    "/dev/ttyUSB0: reconnecting failed: KeyError: 'baud'"
    >>> type(lost.__cause__).__name__
    'KeyError'
    """
    logger.error(
        "reconnecting %s failed: %s: %s; the connection is lost",
        description,
        type(error).__name__,
        error,
        exc_info=error,
    )
    lost = ConnectionLostError(
        f"{description}: reconnecting failed: {type(error).__name__}: {error}"
    )
    lost.__cause__ = error
    return lost
