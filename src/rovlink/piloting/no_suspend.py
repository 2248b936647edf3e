"""SIGTSTP, however it comes, never suspends a piloting tool (the console, the monitor) or a
command that drives the robot (``demo``, ``send``): a stopped tool could not stop the robot,
and what it last sent (thrust) would go on unattended.

In the console, while a prompt reads keys the terminal is in raw mode and Ctrl-Z is a key (bound
to say so). Between one prompt and the next, for the moment a submitted line takes to be handed
on, prompt_toolkit puts the terminal back in its cooked mode: a Ctrl-Z typed then is the
terminal's, which sends SIGTSTP to the console. So does ``kill -TSTP``, or a Ctrl-Z typed at a
terminal while a script's lines run (``rovlink console < dive.txt``), or at a terminal whose
signal keys something turned back on under the monitor (textual's own handler then stops the
process). The signal is caught for as long as the tool runs and said as the key is; only
SIGSTOP, which cannot be caught, stops it (then the driver's keep-alives stop too, and the
controller's link-loss watchdog stops the motors, P17).
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
from collections.abc import Callable, Iterator

__all__ = ["suspension_refused"]


@contextlib.contextmanager
def suspension_refused(say: Callable[[], None]) -> Iterator[None]:
    """Inside, a SIGTSTP calls ``say`` on the running event loop rather than stopping the
    process; the handler before is put back after. With no event loop running (a command whose
    work runs in a worker thread while the main thread waits), ``say`` is called in the handler
    itself, in the main thread. Where signals cannot be caught (not the main thread, Windows),
    or SIGTSTP is ignored already (it cannot suspend then), nothing.

    A plain handler, not the loop's ``add_signal_handler``: that one takes over the signal
    wakeup descriptor, which the monitor's stop on a closed terminal reads from a thread of its
    own (see ``StopOnTermination``), and gives it up when its last handler is removed.
    """
    number = getattr(signal, "SIGTSTP", None)
    try:
        loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
    except RuntimeError:  # (no loop: said from the handler)
        loop = None
    try:
        previous = None if number is None else signal.getsignal(number)
    except ValueError:  # (not the main thread)
        previous = None
    if number is None or previous is None or previous == signal.SIG_IGN:
        yield
        return

    def refuse(_number: int, _frame: object) -> None:
        if loop is None:
            say()
            return
        with contextlib.suppress(RuntimeError):  # (the loop has closed)
            loop.call_soon_threadsafe(say)

    try:
        signal.signal(number, refuse)
    except ValueError:  # (not the main thread)
        yield
        return
    try:
        yield
    finally:
        signal.signal(number, previous)
