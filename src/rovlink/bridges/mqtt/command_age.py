"""How old a command from the broker may be and still move the robot or unlock it.

A broker that stalls (stopped, swapped out, overloaded) keeps what is published to it meanwhile
and hands it over when it resumes. If the bridge's connection outlived the stall, a ``th 90 100``
published seconds before would be carried out then: after a motion timeout would have expired
it, perhaps after its pilot gave up on it. A command's age is known two ways:

* its ``at`` (a JSON request's, Unix time, s), by the publisher's clock and the bridge's;
* the broker's silence as the command arrives: how long one of the bridge's QoS 1 publications
  (its state at least every 2 s) has been waiting for the broker's PUBACK. Whatever the broker
  hands over then may have waited in it that long.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["DEFAULT_MAX_COMMAND_AGE_S", "BrokerSilence", "publication_age_problem"]

#: Motion older than this is not carried out (the CLI's default motion timeout), s.
DEFAULT_MAX_COMMAND_AGE_S = 2.0
#: An "at" a thousand times the clock, give or take this, was written in milliseconds, s.
_A_DAY_S = 86_400.0


class BrokerSilence:
    """How long the broker has left a publication of the bridge unanswered.

    >>> now = [0.0]
    >>> silence = BrokerSilence(clock=lambda: now[0])
    >>> with silence.awaiting_answer():
    ...     now[0] = 3.0
    ...     silence.silent_s()
    3.0
    >>> silence.silent_s()
    0.0
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._started_s: dict[int, float] = {}
        self._tokens = itertools.count()

    @contextmanager
    def awaiting_answer(self) -> Iterator[None]:
        """Around one publication that the broker answers (QoS 1: its PUBACK)."""
        token = next(self._tokens)
        self._started_s[token] = self._clock()
        try:
            yield
        finally:
            del self._started_s[token]

    def silent_s(self) -> float:
        """How long the oldest publication still unanswered has waited (0: none waits)."""
        if not self._started_s:
            return 0.0
        return max(0.0, self._clock() - min(self._started_s.values()))


def publication_age_problem(published_at_s: float, now_s: float, max_age_s: float) -> str | None:
    """Why a command published at ``published_at_s`` (its ``at``) is too old, or too far ahead
    of the bridge's clock (``now_s``), to move the robot; ``None`` if it is not.

    >>> publication_age_problem(100.0, 101.5, 2.0) is None
    True
    >>> publication_age_problem(100.0, 104.5, 2.0)
    'published 4.5 s ago (its "at"): motion older than 2 s is not carried out; publish it again'
    >>> publication_age_problem(1767225600250.0, 1767225600.5, 2.0)
    '"at" is Unix time in seconds: this one looks like milliseconds'
    """
    age_s = now_s - published_at_s
    if age_s > max_age_s:
        return (
            f'published {_seconds(age_s)} s ago (its "at"): motion older than {max_age_s:g} s '
            "is not carried out; publish it again"
        )
    if age_s < -max_age_s:
        if abs(published_at_s / 1000 - now_s) < _A_DAY_S:  # (JavaScript's Date.now(), say)
            return '"at" is Unix time in seconds: this one looks like milliseconds'
        return (
            f'its "at" is {_seconds(-age_s)} s ahead of the bridge\'s clock: motion is not '
            "carried out until the clocks agree"
        )
    return None


def _seconds(duration_s: float) -> str:
    """A duration for a message: tenths, or three figures when an ``at`` is absurdly far off
    (``1e300`` would be written out in 300 digits)."""
    return f"{duration_s:.1f}" if duration_s < 1e6 else f"{duration_s:.3g}"
