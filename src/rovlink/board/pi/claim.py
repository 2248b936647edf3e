"""One controller per PWM board: an exclusive lock on its I²C bus, held while the process lives.

Two controllers on one PCA9685 (the service, and another started by hand for a bench test) would
each write only the pulses they believe changed, so `#stop!` sent to one would not stop what the
other set running, and each would disturb the other's sensor conversions. The lock is a
``flock(2)`` on the bus's device file: the kernel releases it however the process ends (SIGKILL
included), so a controller started after a crash, or ``--neutral`` after it, is never kept out
by a stale lock. Programs that do not lock (``i2cdetect``) are not kept out.
"""

from __future__ import annotations

import errno
import fcntl
import os
from collections.abc import Callable

__all__ = ["BoardInUseError", "claim_exclusively"]


class BoardInUseError(OSError):
    """Another process holds the lock."""


def claim_exclusively(path: str) -> Callable[[], None]:
    """Lock ``path`` for this process; the function that releases it.

    Raises :class:`BoardInUseError` if another process holds it, :class:`OSError` if the file
    cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise BoardInUseError(errno.EBUSY, f"locked by another process ({path})") from None
    except OSError:
        os.close(fd)
        raise
    return lambda: os.close(fd)
