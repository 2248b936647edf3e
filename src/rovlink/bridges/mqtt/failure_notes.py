"""Which failed attempts to reach the broker are worth a warning.

The bridge retries a broker that is away every few seconds, for as long as it stays away: a
warning for each attempt would put one line in the log every 5 s, all day, burying the rest.
The first failure of a kind is said; the same failure again is said once a minute, with the
number of attempts since (the others go to the debug log); a connection made, or another
failure, is said at once.

>>> notes = FailureNotes()
>>> notes.note("cannot connect: connection refused", now_s=0.0)
'cannot connect: connection refused'
>>> notes.note("cannot connect: connection refused", now_s=5.0) is None
True
>>> notes.note("cannot connect: connection refused", now_s=61.0)
'cannot connect: connection refused (2 attempts failed so since the last note)'
"""

from __future__ import annotations

__all__ = ["FailureNotes"]

#: How often a failure that goes on is said again, s.
SAY_AGAIN_EVERY_S = 60.0


class FailureNotes:
    """The failures said, and the attempts not said since."""

    def __init__(self, say_again_every_s: float = SAY_AGAIN_EVERY_S) -> None:
        self._every_s = say_again_every_s
        self._said: str | None = None
        self._said_at_s = 0.0
        self._unsaid = 0

    def note(self, failure: str, now_s: float) -> str | None:
        """What to warn of for ``failure`` at ``now_s`` (seconds, any monotonic clock), or
        ``None``: the same was said less than a minute ago."""
        if failure == self._said and now_s - self._said_at_s < self._every_s:
            self._unsaid += 1
            return None
        text = failure
        if failure == self._said:
            text = f"{failure} ({self._unsaid + 1} attempts failed so since the last note)"
        self._said, self._said_at_s, self._unsaid = failure, now_s, 0
        return text

    def connected(self) -> None:
        """The broker took a connection: its next failure is news."""
        self._said, self._unsaid = None, 0
