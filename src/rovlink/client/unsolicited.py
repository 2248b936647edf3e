"""What the clients do with bytes that answered no query: log them and offer them to a callback."""

from __future__ import annotations

import logging
from collections.abc import Iterable

from rovlink.client.options import StrayCallback
from rovlink.protocol import BadFrame, Event, Frame, Text

__all__ = ["report"]

logger = logging.getLogger("rovlink.client")


def report(events: Iterable[Event], callback: StrayCallback | None) -> None:
    """Log each event (debug text at INFO, dropped frames at WARNING) and pass it on.

    A callback that raises is logged and otherwise ignored: it must not stop the reader.

    Example::

        received = session.receive(data, now)
        report(received.unsolicited, options.on_stray)
    """
    for event in events:
        if isinstance(event, Text):
            logger.info("controller: %s", event.text)
        elif isinstance(event, BadFrame):
            logger.warning("dropped frame %r (%s): %s", event.raw, event.reason, event.detail)
        elif isinstance(event, Frame):
            logger.debug("stray frame %r answers no pending query", event.raw)
        if callback is not None:
            try:
                callback(event)
            except Exception:
                logger.exception("on_stray callback failed on %r", event)
