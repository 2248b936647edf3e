"""What the clients do with what answered no query, and with the session's events.

A library must not fill its user's terminal: on a tether with a bit-error rate of 1e-3 a few
frames a second are dropped, and a program that configured no logging would see each of them
through Python's last-resort handler. So a dropped frame is logged at DEBUG; at most once per
:data:`DROP_WARNING_PERIOD_S` a WARNING says how many were dropped since the last one. The
controller's debug text is logged at INFO, stray frames at DEBUG. Likewise an event callback
that fails on every event (its output a closed pipe) is logged with its traceback once, then
counted: at most one WARNING per :data:`HOOK_FAILURE_WARNING_PERIOD_S` says how many more failed.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable

from rovlink.client.events import (
    ClientEvent,
    EventCallback,
    LinkState,
    MotionExpired,
    ResetSuspected,
)
from rovlink.client.options import StrayCallback
from rovlink.logs import get_logger
from rovlink.protocol import BadFrame, Event, Frame, Text

__all__ = [
    "DROP_WARNING_PERIOD_S",
    "HOOK_FAILURE_WARNING_PERIOD_S",
    "DropLog",
    "HookFailureLog",
    "deliver",
]

logger = get_logger("rovlink.client")

#: At most one warning about dropped frames this often.
DROP_WARNING_PERIOD_S = 10.0
#: At most one warning about a failing event callback's further failures this often.
HOOK_FAILURE_WARNING_PERIOD_S = 10.0


class DropLog:
    """Logs unsolicited events and passes them on; warns about dropped frames periodically.

    >>> from rovlink.protocol import BadFrame, Reason
    >>> log = DropLog()
    >>> log.report([BadFrame(Reason.CHECKSUM, b"$qd.1x!", "")], None, now=0.0)
    >>> log.dropped_since_warning
    0
    """

    def __init__(self, period_s: float = DROP_WARNING_PERIOD_S) -> None:
        self.period_s = period_s
        self.dropped_since_warning = 0
        self._last_warning_at = float("-inf")
        self._callback_failures = HookFailureLog("on_stray")

    def report(self, events: Iterable[Event], callback: StrayCallback | None, now: float) -> None:
        """Log each event and pass it to ``callback`` (a callback that raises is logged once,
        then counted: :class:`HookFailureLog`).

        Example::

            received = session.receive(data, now)
            drops.report(received.unsolicited, options.on_stray, now)
        """
        for event in events:
            if isinstance(event, Text):
                logger.info("controller: %s", event.text)
            elif isinstance(event, BadFrame):
                logger.debug("dropped frame %r (%s): %s", event.raw, event.reason, event.detail)
                self.dropped_since_warning += 1
            elif isinstance(event, Frame):
                logger.debug("stray frame %r answers no pending query", event.raw)
            if callback is not None:
                try:
                    callback(event)
                except (Exception, SystemExit) as error:  # (SystemExit: it ends a reader thread)
                    self._callback_failures.report(callback, event, error)
        if self.dropped_since_warning and now - self._last_warning_at >= self.period_s:
            logger.warning(
                "%d received frame(s) dropped (bad checksum or malformed) since "
                "the last report; see the link counters",
                self.dropped_since_warning,
            )
            self.dropped_since_warning = 0
            self._last_warning_at = now


class HookFailureLog:
    """Logs the failures of event callbacks: each callback's first with its traceback, then
    how many more, at most once per :data:`HOOK_FAILURE_WARNING_PERIOD_S`.

    >>> failures = HookFailureLog("on_event", clock=lambda: 0.0)
    >>> hook = print
    >>> failures.report(hook, "event", ValueError("bad"))  # logged, with the traceback
    >>> failures.report(hook, "event", ValueError("bad"))  # counted
    >>> failures.unsaid(hook)
    1
    """

    def __init__(self, name: str = "on_event", clock: Callable[[], float] = time.monotonic) -> None:
        self._name = name  # what the user calls the callbacks: on_event, on_stray
        self._clock = clock
        # By the callback's id: a callback need not be hashable, and each client keeps its
        # callbacks (``on_event``, the subscribers) alive as long as this log.
        self._said_at: dict[int, float] = {}
        self._unsaid: dict[int, int] = {}

    def unsaid(self, callback: object) -> int:
        """How many failures of ``callback`` were counted since it was last logged.

        Example::

            failures.unsaid(options.on_event)   # 0 while it has not failed again
        """
        return self._unsaid.get(id(callback), 0)

    def report(self, callback: object, event: object, error: BaseException) -> None:
        """Log that ``callback`` raised ``error`` on ``event``, or count it (see the class).

        Example::

            try:
                callback(event)
            except Exception as error:
                failures.report(callback, event, error)
        """
        key, now = id(callback), self._clock()
        said_at = self._said_at.get(key)
        if said_at is None:
            logger.error(
                "%s callback failed on %r (its further failures are counted: a warning "
                "at most every %g s)",
                self._name,
                event,
                HOOK_FAILURE_WARNING_PERIOD_S,
                exc_info=error,
            )
            self._said_at[key] = now
            return
        unsaid = self._unsaid.get(key, 0) + 1
        if now - said_at >= HOOK_FAILURE_WARNING_PERIOD_S:
            logger.warning(
                "%s callback failed %d more times since it was last logged, last on %r: %r",
                self._name,
                unsaid,
                event,
                error,
            )
            self._said_at[key] = now
            unsaid = 0
        self._unsaid[key] = unsaid


def deliver(
    events: Iterable[ClientEvent],
    notices: Iterable[ClientEvent],
    callback: EventCallback | None,
    failures: HookFailureLog,
) -> None:
    """Log the session's notices and hand every event to ``callback`` (its errors go to
    ``failures``).

    Example::

        deliver(session.take_events(), session.take_notices(), options.on_event, failures)
    """
    for notice in notices:
        if isinstance(notice, ResetSuspected):
            logger.warning(
                "controller reset suspected after %d consecutive timeouts: "
                "checksum mode re-asserted; the robot is locked after a reset",
                notice.consecutive_timeouts,
            )
        elif isinstance(notice, MotionExpired):
            frames = " ".join(str(command) for command in notice.commands)
            logger.warning("motion not renewed within motion_timeout: sent %s", frames)
        elif isinstance(notice, LinkState):
            level = logging.WARNING if notice.state == "lost" else logging.INFO
            logger.log(level, "link %s: %s", notice.state, notice.detail)
    if callback is None:
        return
    for event in events:
        try:
            callback(event)
        except (Exception, SystemExit) as error:  # (SystemExit too: it ends a reader thread)
            failures.report(callback, event, error)
