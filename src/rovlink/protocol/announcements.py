"""What rovlink's controllers tell every line with debug output on (P5): the lock changing, and
another line taking over the driving. The controller prints these words and the tools read them
back (:func:`read_announcement`), so they are written here once.

The protocol has no query for the lock (P4); a tool that hears these lines learns of a
``#stop!`` sent on another line, or of a failsafe. A controller that prints other words (another
firmware) is simply never recognised: its tools show the lock as they last sent it.

>>> heard = read_announcement(DEBUG_PREFIX + locked_text(STOP_COMMAND))
>>> str(heard.kind), heard.detail
('locked', 'stop command')
>>> str(read_announcement("debug: motors unlocked").kind)
'unlocked'
>>> read_announcement("debug: vertical thrust +20 %") is None
True
"""

from __future__ import annotations

from rovlink.protocol.frozen import frozen
from rovlink.protocol.text_enum import StrEnum

__all__ = [
    "DEBUG_PREFIX",
    "STOP_COMMAND",
    "UNLOCKED_TEXT",
    "Announcement",
    "AnnouncementKind",
    "another_line_text",
    "locked_text",
    "read_announcement",
]

#: What begins every debug line the controller writes (P5).
DEBUG_PREFIX = "debug: "
#: The lock was lifted (``#start!`` from any line).
UNLOCKED_TEXT = "motors unlocked"
#: Why the motors were stopped when a line sent ``#stop!`` (other reasons are failsafes).
STOP_COMMAND = "stop command"
_LOCKED_SUFFIX = ": motors stopped and locked"
_ANOTHER_LINE_SUFFIX = " from another line: it drives now, and the link-loss failsafe follows it"


class AnnouncementKind(StrEnum):
    """What an announcement says."""

    LOCKED = "locked"
    UNLOCKED = "unlocked"
    ANOTHER_LINE_DRIVES = "another line drives"


@frozen
class Announcement:
    """One announcement heard: its kind, and ``detail``: why the motors were stopped
    (:data:`STOP_COMMAND`, or a failsafe's reason), the frame that took over the driving
    (``<th.90.20>``), or ``""``."""

    __slots__ = ("detail", "kind")
    __match_args__ = ("kind", "detail")

    kind: AnnouncementKind
    detail: str

    def __init__(self, kind: AnnouncementKind, detail: str = "") -> None:
        object.__setattr__(self, "kind", kind)
        object.__setattr__(self, "detail", detail)


def locked_text(why: str) -> str:
    """The announcement of a stop, without the debug prefix.

    >>> locked_text("failsafe: no valid frame for 2 s")
    'failsafe: no valid frame for 2 s: motors stopped and locked'
    """
    return why + _LOCKED_SUFFIX


def another_line_text(frame: str) -> str:
    """The announcement that the line that sent ``frame`` (as a debug line describes it,
    ``<th.90.20>``) drives now, without the debug prefix."""
    return frame + _ANOTHER_LINE_SUFFIX


def read_announcement(text: str) -> Announcement | None:
    """The announcement in a line of text received between frames, or ``None`` if it is none
    (other debug output, line noise, another controller's words). It never raises.

    >>> read_announcement("debug: leak: motors stopped and locked").detail
    'leak'
    >>> read_announcement("debug: <th.90.20> from another line: it drives now, and the "
    ...                   "link-loss failsafe follows it").detail
    '<th.90.20>'
    """
    text = text.strip()
    if not text.startswith(DEBUG_PREFIX):
        return None
    said = text[len(DEBUG_PREFIX) :]
    if said == UNLOCKED_TEXT:
        return Announcement(AnnouncementKind.UNLOCKED)
    if said.endswith(_LOCKED_SUFFIX) and len(said) > len(_LOCKED_SUFFIX):
        return Announcement(AnnouncementKind.LOCKED, said[: -len(_LOCKED_SUFFIX)])
    if said.endswith(_ANOTHER_LINE_SUFFIX) and len(said) > len(_ANOTHER_LINE_SUFFIX):
        return Announcement(
            AnnouncementKind.ANOTHER_LINE_DRIVES, said[: -len(_ANOTHER_LINE_SUFFIX)]
        )
    return None
