"""Run an asyncio command so that Ctrl-C (and SIGTERM, SIGHUP, which arrive as it) cancels it
cleanly on every supported Python.

Python 3.11's ``asyncio.run`` takes Ctrl-C as a cancellation of the main task: the command's
``finally`` blocks run (``#stop!``, a recording finished, the client closed) and
``KeyboardInterrupt`` is raised once the task has ended. Python 3.10's raises
``KeyboardInterrupt`` wherever the interpreter happens to be, inside the event loop's own code
too: landing while a future wakes the task that awaits it, it leaves that task asleep for ever,
and the run's shutdown, which waits for every task to end, never returns. On 3.10 this module
does what 3.11 does.
"""

from __future__ import annotations

import asyncio
import signal
import sys
import threading
from collections.abc import Coroutine
from typing import Any, TypeVar

__all__ = ["run_async"]

T = TypeVar("T")


def run_async(main: Coroutine[Any, Any, T]) -> T:
    """Run ``main`` on a new event loop and return its result; Ctrl-C cancels it, and
    ``KeyboardInterrupt`` is raised when it has ended. A second Ctrl-C interrupts at once.

    Example::

        run_async(_serve(args, broker))
    """
    if sys.version_info >= (3, 11):
        return asyncio.run(main)
    return run_cancelled_by_ctrl_c(main)


def run_cancelled_by_ctrl_c(main: Coroutine[Any, Any, T]) -> T:
    """``asyncio.run`` with Python 3.11's handling of Ctrl-C, on any Python (the tests run it on
    the newest too). What :func:`run_async` uses on 3.10."""
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
            return loop.run_until_complete(task)
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
