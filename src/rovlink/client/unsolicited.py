"""What the clients do with what answered no query, and with the session's events.

A library must not fill its user's terminal: on a tether with a bit-error rate of 1e-3 a few
frames a second are dropped, and a program that configured no logging would see each of them
through Python's last-resort handler. So a dropped frame is logged at DEBUG; at most once per
:data:`DROP_WARNING_PERIOD_S` a WARNING says how many were dropped since the last one. The
controller's debug text is logged at INFO, stray frames at DEBUG.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

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

__all__ = ["DROP_WARNING_PERIOD_S", "DropLog", "deliver"]

logger = get_logger("rovlink.client")

#: At most one warning about dropped frames this often.
DROP_WARNING_PERIOD_S = 10.0


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

    def report(self, events: Iterable[Event], callback: StrayCallback | None, now: float) -> None:
        """Log each event and pass it to ``callback`` (a callback that raises is logged).

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
                except (Exception, SystemExit):  # (SystemExit too: it ends a reader thread)
                    logger.exception("on_stray callback failed on %r", event)
        if self.dropped_since_warning and now - self._last_warning_at >= self.period_s:
            logger.warning(
                "%d received frame(s) dropped (bad checksum or malformed) since "
                "the last report; see the link counters",
                self.dropped_since_warning,
            )
            self.dropped_since_warning = 0
            self._last_warning_at = now


def deliver(
    events: Iterable[ClientEvent], notices: Iterable[ClientEvent], callback: EventCallback | None
) -> None:
    """Log the session's notices and hand every event to ``callback`` (errors are logged).

    Example::

        deliver(session.take_events(), session.take_notices(), options.on_event)
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
        except (Exception, SystemExit):  # (SystemExit too: it ends a reader thread)
            logger.exception("on_event callback failed on %r", event)
