"""The link's health as a tool sees it: reply times, failed queries, silence."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["LinkHealth"]

#: Weight of the newest reply time in the running average.
_AVERAGE_WEIGHT = 0.2
#: Failed queries in a row after which the link counts as silent.
_SILENT_AFTER = 3


@dataclass(slots=True)
class LinkHealth:
    """Reply times and failures of the queries a tool made (retries and timeouts included).

    >>> health = LinkHealth()
    >>> health.record_reply(0.004, now_s=10.0)
    >>> health.record_failure("no reply", now_s=11.0)
    >>> health.status, health.consecutive_failures
    ('failing', 1)
    """

    #: Seconds from sending a query to its last reply (retries included), latest and averaged.
    last_reply_s: float | None = None
    average_reply_s: float | None = None
    replies: int = 0
    failures: int = 0
    consecutive_failures: int = 0
    last_reply_at_s: float | None = None
    last_error: str | None = None

    def record_reply(self, reply_s: float, now_s: float) -> None:
        """A query answered ``reply_s`` after it was sent."""
        self.last_reply_s = reply_s
        average = self.average_reply_s
        self.average_reply_s = (
            reply_s if average is None else average + _AVERAGE_WEIGHT * (reply_s - average)
        )
        self.replies += 1
        self.consecutive_failures = 0
        self.last_reply_at_s = now_s

    def record_failure(self, error: str, now_s: float) -> None:
        """A query that got no valid reply (after the driver's retries)."""
        del now_s  # the silence is measured from the last reply
        self.failures += 1
        self.consecutive_failures += 1
        self.last_error = error

    def record_heard(self, now_s: float) -> None:
        """A reply to a query of the driver's own (a keep-alive): the link answers, though
        no reply time of the tool's is measured."""
        self.consecutive_failures = 0
        self.last_reply_at_s = now_s

    def record_unanswered(self, error: str) -> None:
        """A query of the driver's own got no valid reply: counted toward a silent link (a
        tool that queries nothing itself would else show it ``ok`` for ever), not among the
        tool's failed queries."""
        self.consecutive_failures += 1
        self.last_error = error

    def silent_s(self, now_s: float) -> float | None:
        """Seconds since the last reply; ``None`` before the first."""
        if self.last_reply_at_s is None:
            return None
        return now_s - self.last_reply_at_s

    @property
    def status(self) -> str:
        """``waiting`` (nothing yet), ``ok``, ``failing`` (the last query failed) or ``no reply``
        (several in a row failed, or none ever succeeded)."""
        if self.consecutive_failures >= _SILENT_AFTER or (self.failures and not self.replies):
            return "no reply"
        if self.consecutive_failures:
            return "failing"
        return "ok" if self.last_reply_at_s is not None else "waiting"
