"""How long the link-loss failsafe (P17) may wait on a real board, whose thrusters really push.

P17 lets a controller's ``watchdog_s`` be any length, 0 turning it off: handy on the simulator,
where a person types commands by hand. On a robot the failsafe is what stops the thrusters when
the tether, the serial adapter or the host dies, so a board refuses to run without it, and
refuses a wait so long that the robot is gone before it acts. Any valid frame keeps the link
alive (P17), and rovlink's host driver and console send a query every idle second, so no
command typed by hand needs the failsafe off; the longest wait still stops a robot at 1 m/s
within a few metres.
"""

from __future__ import annotations

import math

__all__ = ["MAX_BOARD_WATCHDOG_S", "MIN_BOARD_WATCHDOG_S", "board_watchdog_problem"]

#: The shortest link-loss wait on a board, s: a few control periods and a frame at 9600 baud.
MIN_BOARD_WATCHDOG_S = 0.1
#: The longest link-loss wait on a board, s.
MAX_BOARD_WATCHDOG_S = 10.0


def board_watchdog_problem(watchdog_s: float) -> str | None:
    """What is wrong with ``watchdog_s`` as a real board's link-loss failsafe, or None.

    >>> board_watchdog_problem(2.0) is None
    True
    >>> print(board_watchdog_problem(3600.0))
    must be 0.1–10 s on a robot, got 3600: a dead link would leave the thrusters running that long
    """
    bounds = f"{MIN_BOARD_WATCHDOG_S:g}–{MAX_BOARD_WATCHDOG_S:g} s"
    if watchdog_s == 0:
        return (
            f"must be {bounds} on a robot, got 0, which turns the link-loss failsafe off (P17): "
            "a dead link would leave the thrusters running (rovlink's console and host driver "
            "keep the link alive with a query every idle second)"
        )
    if not math.isfinite(watchdog_s) or watchdog_s < MIN_BOARD_WATCHDOG_S:
        return f"must be {bounds} on a robot, got {watchdog_s:g}"
    if watchdog_s > MAX_BOARD_WATCHDOG_S:
        return (
            f"must be {bounds} on a robot, got {watchdog_s:g}: a dead link would leave the "
            "thrusters running that long"
        )
    return None
