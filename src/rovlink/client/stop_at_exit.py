"""The ``#stop!`` a client sends as it lets go of a robot it moved, bounded in time, and sent for
the clients a program leaves open as it ends.

A robot driver sends zero on shutdown: a program that moved the robot and then closed its client,
or ended with it open (the end of its script, ``sys.exit()``, an uncaught error, ``asyncio.run``
returning), left it driving until the controller's link-loss watchdog (P17). Both clients send
that ``#stop!`` through :func:`stop_within`, which never holds the caller up for longer than
:data:`STOP_WAIT_S`: the write is a thread's of its own, and a line that takes nothing (a write
waits up to 2 s for room, ``rfc2217://``'s up to its socket's 5 s) is left to the controller's
failsafe. The clients still open as the program ends are stopped the same way by an ``atexit``
handler, one after the other, so the exit waits at most that long for each; not by a child the
program forked, which shares its ports but not its driving.
"""

from __future__ import annotations

import atexit
import os
import threading
import weakref
from collections.abc import Callable
from typing import Protocol

from rovlink.client.errors import ConnectionLostError
from rovlink.logs import get_logger

__all__ = ["STOP_WAIT_S", "forked_child_error", "stop_at_exit", "stop_within"]

#: How long the ``#stop!`` of a close, or of a program's end, is waited for.
STOP_WAIT_S = 0.5

logger = get_logger("rovlink.client")


class _StoppedAtExit(Protocol):
    @property
    def description(self) -> str: ...

    def _stop_at_exit(self) -> None: ...

    def _forked(self, error: ConnectionLostError) -> None: ...


#: The clients open in this process (either kind): each is stopped as the program ends.
_open_clients: weakref.WeakSet[_StoppedAtExit] = weakref.WeakSet()


def stop_at_exit(client: _StoppedAtExit, *, wanted: bool = True) -> None:
    """Have ``client`` send its ``#stop!`` (its ``_stop_at_exit``) if it is still open as the
    program ends (``wanted=False``: no longer, it has been closed).

    Example::

        stop_at_exit(client)                # once it is open
        stop_at_exit(client, wanted=False)  # as it closes
    """
    if wanted:
        _open_clients.add(client)
    else:
        _open_clients.discard(client)


def stop_within(write_stop: Callable[[], object], description: str) -> bool:
    """Run ``write_stop`` in a thread of its own and wait for it at most :data:`STOP_WAIT_S`;
    False, with a warning naming ``description`` (the port), if it has not ended by then (it is
    left to end in the background). An error it raises is logged, not raised.

    Example::

        stop_within(lambda: link.write(b"#stop!"), link.description)
    """
    writer = threading.Thread(
        target=_logging_errors,
        args=(write_stop, description),
        name=f"rovlink stop ({description})",
        daemon=True,
    )
    writer.start()
    writer.join(STOP_WAIT_S)
    if writer.is_alive():
        logger.warning(
            "%s: #stop! not written within %g s (the line takes nothing); letting go without "
            "it: the controller's link-loss failsafe stops the robot",
            description,
            STOP_WAIT_S,
        )
        return False
    return True


def _logging_errors(write_stop: Callable[[], object], description: str) -> None:
    try:
        write_stop()
    except Exception:  # (a thread's error would otherwise go to stderr, or nowhere)
        logger.exception("%s: writing #stop!", description)


def _stop_open_clients() -> None:
    for client in list(_open_clients):
        try:
            client._stop_at_exit()
        except Exception:  # (the others are stopped all the same)
            logger.exception("stopping %s as the program ends", client.description)


def forked_child_error(description: str, parent_pid: int) -> ConnectionLostError:
    """What every call of a client raises in a child made with ``os.fork()``.

    >>> print(forked_child_error("/dev/ttyUSB0", 1234))  # doctest: +NORMALIZE_WHITESPACE
    /dev/ttyUSB0: this client is process 1234's, and this process is a child it made with
    os.fork(): it shares that port, and writes, reads and closes nothing of it; connect a client
    of its own
    """
    return ConnectionLostError(
        f"{description}: this client is process {parent_pid}'s, and this process is a child it "
        "made with os.fork(): it shares that port, and writes, reads and closes nothing of it; "
        "connect a client of its own"
    )


def _in_forked_child() -> None:
    # A child made with os.fork() shares the program's ports, not its driving: its calls would
    # write on the parent's port and take its replies, and its close() (or leaving a with block,
    # or its exit) would send #stop! and shut the parent's link down under it.
    parent_pid = os.getppid()
    for client in list(_open_clients):
        client._forked(forked_child_error(client.description, parent_pid))
    _open_clients.clear()


atexit.register(_stop_open_clients)
if hasattr(os, "register_at_fork"):  # (not on Windows)
    os.register_at_fork(after_in_child=_in_forked_child)
