"""SIGTSTP, however it comes, never suspends the console: a stopped console could not stop the
robot, and what it last sent (thrust) would go on unattended.

While a prompt reads keys the terminal is in raw mode and Ctrl-Z is a key (bound to say so).
Between one prompt and the next, for the moment a submitted line takes to be handed on,
prompt_toolkit puts the terminal back in its cooked mode: a Ctrl-Z typed then is the terminal's,
which sends SIGTSTP to the console. So does ``kill -TSTP``, or a Ctrl-Z typed at a terminal while
a script's lines run (``rovlink console < dive.txt``). The signal is caught for as long as the
console runs and said as the key is; only SIGSTOP, which cannot be caught, stops it (then the
driver's keep-alives stop too, and the controller's link-loss watchdog stops the motors, P17).
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
    process; the handler before is put back after. Where the loop cannot watch signals (not the
    main thread, Windows), or SIGTSTP is ignored already (it cannot suspend then), nothing."""
    number = getattr(signal, "SIGTSTP", None)
    loop = asyncio.get_running_loop()
    try:
        previous = None if number is None else signal.getsignal(number)
    except ValueError:  # (not the main thread)
        previous = None
    if number is None or previous is None or previous == signal.SIG_IGN:
        yield
        return
    try:
        loop.add_signal_handler(number, say)
    except (NotImplementedError, RuntimeError, ValueError):
        yield
        return
    try:
        yield
    finally:
        loop.remove_signal_handler(number)
        signal.signal(number, previous)
