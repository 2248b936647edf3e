"""Run an asyncio command so that Ctrl-C (and SIGTERM, SIGHUP, which arrive as it) cancels it
cleanly on every supported Python.

Python 3.11's ``asyncio.run`` takes Ctrl-C as a cancellation of the main task: the command's
``finally`` blocks run (``#stop!``, a recording finished, the client closed) and
``KeyboardInterrupt`` is raised once the task has ended. Python 3.10's raises
``KeyboardInterrupt`` wherever the interpreter happens to be, inside the event loop's own code
too: landing while a future wakes the task that awaits it, it leaves that task asleep for ever,
and the run's shutdown, which waits for every task to end, never returns. On 3.10 this module
does what 3.11 does.

SIGTERM, SIGHUP and SIGQUIT cancel the main task from the event loop on every Python, whatever
SIGINT's handler: in a background job SIGINT is ignored, and the command line's own handler for
them would then raise KeyboardInterrupt wherever the interpreter is, as 3.10's Ctrl-C did.

Once a signal has cancelled the main task, SIGTERM and SIGHUP change nothing: a terminal closed
or a service stopped while the command is on its way out must not cut its ``#stop!`` short. A
second Ctrl-C is the user's own, and interrupts at once.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
import signal
import sys
import threading
from collections.abc import Callable, Coroutine
from types import TracebackType
from typing import Any, TypeVar

__all__ = ["StopOnTermination", "run_async", "serve_async"]

logger = logging.getLogger(__name__)

T = TypeVar("T")


def run_async(main: Coroutine[Any, Any, T]) -> T:
    """Run ``main`` on a new event loop and return its result; Ctrl-C cancels it, and
    ``KeyboardInterrupt`` is raised when it has ended. A second Ctrl-C interrupts at once.

    Example::

        run_async(_serve(args, broker))
    """
    return _run(main, Ending())


def serve_async(main: Coroutine[Any, Any, None], program: str) -> None:
    """:func:`run_async` for a serving command (a bridge, run as a service): SIGTERM and
    SIGHUP, how a service manager or a closed SSH session stops it, end it cleanly with
    ``PROGRAM stopped`` and return (status 0: ``systemctl stop`` counts anything else as a
    failure); Ctrl-C and SIGQUIT still raise ``KeyboardInterrupt`` (status 130), as for every
    command.

    Example::

        serve_async(_serve(args, broker), "rovlink mqtt")
    """
    from rovlink.cli.interrupt import say_last  # noqa: PLC0415 - (the rest of it is not needed)

    ending = Ending()
    try:
        _run(main, ending)
    except KeyboardInterrupt:
        if not ending.stopped_as_a_service:
            raise
        say_last(f"{program} stopped")


def _run(main: Coroutine[Any, Any, T], ending: Ending) -> T:
    if sys.version_info >= (3, 11):
        return asyncio.run(ended_by_termination(main, ending))
    return run_cancelled_by_ctrl_c(ended_by_termination(main, ending), ending)


#: The signals that stop a service (a service manager's, a closed terminal's): for a serving
#: command a clean end, where Ctrl-C and Ctrl-\ say "interrupted".
_SERVICE_STOPS = frozenset(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)
)


class Ending:
    """Whether a signal has cancelled the command's main task (shared by the handlers)."""

    def __init__(self) -> None:
        self.cancelled = False
        #: Whether the signal that cancelled it was SIGTERM or SIGHUP (not Ctrl-C, SIGQUIT).
        self.stopped_as_a_service = False

    def seen_on(self, task: asyncio.Task[Any]) -> bool:
        """Whether ``task`` is being cancelled already: by a signal handled here, or (3.11
        and later) by ``asyncio.run``'s own handling of Ctrl-C."""
        cancelling = getattr(task, "cancelling", None)  # (3.11 and later)
        return self.cancelled or (cancelling is not None and cancelling() > 0)


async def ended_by_termination(main: Coroutine[Any, Any, T], ending: Ending) -> T:
    """Await ``main``, cancelled by the first SIGTERM, SIGHUP or SIGQUIT (each a callback of
    the event loop, which runs between its callbacks, never inside one); ``KeyboardInterrupt``
    when a signal has cancelled it. A signal ignored on entry (``nohup``) stays ignored; the
    handlers before are put back after. Where the loop cannot watch signals (Windows),
    ``main`` alone."""
    loop = asyncio.get_running_loop()
    task = asyncio.current_task()
    assert task is not None  # (a coroutine run by asyncio.run is a task's)

    def terminate(number: int) -> None:
        if ending.seen_on(task):  # (on its way out already: not cut short)
            return
        ending.cancelled = True
        ending.stopped_as_a_service = number in _SERVICE_STOPS
        task.cancel()

    previous: dict[int, Any] = {}
    for name in ("SIGTERM", "SIGHUP", "SIGQUIT"):
        number = getattr(signal, name, None)  # (no SIGHUP, SIGQUIT on Windows)
        if number is None:
            continue
        handler = signal.getsignal(number)
        if handler is signal.SIG_IGN:
            continue
        try:
            loop.add_signal_handler(number, terminate, number)
        except (NotImplementedError, RuntimeError, ValueError):  # Windows; not the main thread
            continue
        previous[number] = handler
    try:
        result = await main
    except asyncio.CancelledError:
        if ending.cancelled:  # (by SIGTERM, SIGHUP, or on 3.10 Ctrl-C: KeyboardInterrupt all)
            raise KeyboardInterrupt from None
        raise
    else:
        # Ended by a signal all the same: a framework (textual) took the cancellation as a
        # request to leave, and returned. The exit status says interrupted, as for any command.
        if ending.seen_on(task):
            raise KeyboardInterrupt
        return result
    finally:
        for number, handler in previous.items():
            loop.remove_signal_handler(number)  # (which leaves SIG_DFL)
            signal.signal(number, handler)


def run_cancelled_by_ctrl_c(main: Coroutine[Any, Any, T], ending: Ending | None = None) -> T:
    """``asyncio.run`` with Python 3.11's handling of Ctrl-C, on any Python (the tests run it on
    the newest too); a Ctrl-C that cancels the task is noted in ``ending``. What
    :func:`run_async` uses on 3.10."""
    loop = asyncio.new_event_loop()
    try:
        asyncio.set_event_loop(loop)
        task = loop.create_task(main)
        interrupts = 0

        def on_ctrl_c(signum: int, frame: object) -> None:
            nonlocal interrupts
            interrupts += 1
            if interrupts > 1:
                raise KeyboardInterrupt
            if ending is not None:
                ending.cancelled = True
            # The loop cancels the task on its next turn. The handler runs between any two
            # bytecodes of this thread, the loop's own included, so it only queues (a deque's
            # append, and a byte to the loop's self-pipe, which also wakes a select()).
            loop.call_soon_threadsafe(task.cancel)

        installed = (
            threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.default_int_handler
        )
        if installed:
            signal.signal(signal.SIGINT, on_ctrl_c)
        try:
            result = loop.run_until_complete(task)
            if interrupts:  # it came as the task took its last step, or after: too late
                raise KeyboardInterrupt
            return result
        except asyncio.CancelledError:
            if interrupts:
                raise KeyboardInterrupt from None
            raise
        finally:
            if installed and signal.getsignal(signal.SIGINT) is on_ctrl_c:
                signal.signal(signal.SIGINT, signal.default_int_handler)
    finally:
        try:
            _cancel_remaining_tasks(loop)
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.run_until_complete(loop.shutdown_default_executor())
        finally:
            asyncio.set_event_loop(None)
            loop.close()


def _cancel_remaining_tasks(loop: asyncio.AbstractEventLoop) -> None:
    """Cancel the tasks the main task left running and let them finish, as ``asyncio.run``
    does; an error one of them ends with goes to the loop's exception handler."""
    remaining = asyncio.all_tasks(loop)
    if not remaining:
        return
    for task in remaining:
        task.cancel()
    loop.run_until_complete(asyncio.gather(*remaining, return_exceptions=True))
    for task in remaining:
        if not task.cancelled() and task.exception() is not None:
            loop.call_exception_handler(
                {
                    "message": "unhandled exception during the command's shutdown",
                    "exception": task.exception(),
                    "task": task,
                }
            )


#: How long a command may take to leave after a terminating signal once its ``#stop!`` is out.
LEAVE_BOUND_S = 3.0
#: What the process exits with when it has to be ended without its event loop (130: interrupted).
_EXIT_INTERRUPTED = 130
_TERMINATING = frozenset(
    getattr(signal, name)
    for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
    if hasattr(signal, name)
)


class StopOnTermination:
    """While in effect, SIGINT, SIGTERM, SIGHUP and SIGQUIT call ``emergency_stop`` at once in
    a thread of their own, and end the process ``LEAVE_BOUND_S`` later if it has not ended by then.

    For a command whose event loop may block: textual writes to the terminal through a thread
    and a bounded queue, and on a closed terminal that thread dies or stalls, so the loop
    blocks in ``queue.put`` for ever, before the handler that would cancel the command (a
    callback of that loop) can run. Python runs its signal handlers in the main thread only,
    which is the one blocked; the signal-wakeup descriptor is written by whichever thread the
    signal lands on, so it is taken here and read by a thread of ours, which hands every byte on
    to the loop's own descriptor (the loop's handlers still run, when it can run them).
    Entered in the main thread, inside the running loop (after :func:`run_async` set up its
    handlers). Example::

        with StopOnTermination(client.emergency_stop, "rovlink monitor"):
            await app.run_async()
    """

    def __init__(
        self, emergency_stop: Callable[[], object], program: str, bound_s: float = LEAVE_BOUND_S
    ) -> None:
        self._emergency_stop = emergency_stop
        self._program = program
        self._bound_s = bound_s
        self._left = threading.Event()
        self._read_fd = -1
        self._write_fd = -1
        self._previous_fd = -1
        self._thread: threading.Thread | None = None

    def __enter__(self) -> StopOnTermination:
        if threading.current_thread() is not threading.main_thread():
            return self  # (set_wakeup_fd is the main thread's; a program's thread: no net)
        self._read_fd, self._write_fd = os.pipe()
        os.set_blocking(self._write_fd, False)  # (the C handler must never block)
        self._previous_fd = signal.set_wakeup_fd(self._write_fd)
        self._thread = threading.Thread(target=self._watch, name="rovlink stop", daemon=True)
        self._thread.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self._left.set()  # (a forced exit counting down is called off)
        if self._thread is None:
            return
        signal.set_wakeup_fd(self._previous_fd)
        os.close(self._write_fd)  # the thread reads the end of the pipe, and returns

    def _watch(self) -> None:
        stopped = False
        try:
            while data := os.read(self._read_fd, 64):
                if self._previous_fd >= 0:  # the loop sees its signals as before
                    with contextlib.suppress(OSError):
                        os.write(self._previous_fd, data)
                if stopped or not _TERMINATING.intersection(data):
                    continue
                stopped = True
                threading.Thread(target=self._end_if_stuck, daemon=True).start()
                try:
                    self._emergency_stop()
                except Exception:  # (the signals must still reach the loop, the exit armed)
                    logger.exception("%s: #stop! could not be written at once", self._program)
        finally:
            os.close(self._read_fd)

    def _end_if_stuck(self) -> None:
        if self._left.wait(self._bound_s):
            return
        # The command could not leave (its loop is blocked): #stop! is out, so end it here.
        with contextlib.suppress(OSError, ValueError):
            os.write(2, f"{self._program}: interrupted\n".encode())
        os._exit(_EXIT_INTERRUPTED)
