"""What the piloting tools (``rovlink console``, ``rovlink monitor``) share.

* :class:`CommandedState` — the lock, vertical mode and set-points as this tool last sent them:
  the protocol has no query for them, so the tools say "as last sent", never "is".
* :class:`TrackedClient` — an asyncio client that records every frame it sends into that state
  and times its queries into a :class:`LinkHealth`.
* :func:`reading_text` — a reply in words, ``qd → 123 cm``.
"""

from rovlink.piloting.commanded import CommandedState, LockState
from rovlink.piloting.health import LinkHealth
from rovlink.piloting.readings import reading_text, reply_text
from rovlink.piloting.tracked import SentFrame, TrackedClient

__all__ = [
    "CommandedState",
    "LinkHealth",
    "LockState",
    "SentFrame",
    "TrackedClient",
    "reading_text",
    "reply_text",
]
