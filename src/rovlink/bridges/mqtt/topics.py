"""The topics of one robot: ``rovlink/ID/`` + ``telemetry``, ``state``, ``events``, ``cmd``,
``cmd/reply``."""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = [
    "ROOT",
    "Topics",
    "check_robot_id",
    "publish_topic_problem",
    "response_topic_problem",
    "robot_of",
]

#: Every topic of the bridges is under this.
ROOT = "rovlink"
_ROBOT_ID = re.compile(r"[A-Za-z0-9_.-]{1,64}")
#: What a bridge publishes or reads under ``rovlink/ID/`` (``cmd/reply`` is for replies).
_BRIDGE_TOPICS = ("telemetry", "state", "events", "cmd")
#: MQTT's limit on a topic name, in UTF-8 bytes.
_MAX_TOPIC_BYTES = 65535


def check_robot_id(robot_id: str) -> str:
    """``robot_id`` if it can be one level of a topic, else ``ValueError`` saying why.

    >>> check_robot_id("rov-1")
    'rov-1'
    >>> check_robot_id("a/b")
    Traceback (most recent call last):
    ...
    ValueError: robot id 'a/b': use 1–64 letters, digits, '-', '_' or '.' (it is a topic level)
    """
    if not _ROBOT_ID.fullmatch(robot_id):
        raise ValueError(
            f"robot id {robot_id!r}: use 1–64 letters, digits, '-', '_' or '.' "
            "(it is a topic level)"
        )
    return robot_id


def publish_topic_problem(topic: str) -> str | None:
    """Why ``topic`` cannot be published to (a wildcard, empty, too long), or ``None``.

    A request's response topic comes from whoever sent it; the MQTT client refuses to publish
    to a bad one with an exception, so it is checked first.

    >>> publish_topic_problem("answers/me") is None
    True
    >>> publish_topic_problem("answers/+/me")
    "contains the wildcard '+'"
    """
    if not topic:
        return "is empty"
    for character in ("+", "#", "\0"):
        if character in topic:
            what = "the null character" if character == "\0" else f"the wildcard {character!r}"
            return f"contains {what}"
    try:
        size_bytes = len(topic.encode("utf-8"))
    except UnicodeEncodeError:
        return "is not valid UTF-8"
    if size_bytes > _MAX_TOPIC_BYTES:
        return f"is {size_bytes} bytes long; a topic is at most {_MAX_TOPIC_BYTES}"
    return None


def response_topic_problem(topic: str) -> str | None:
    """Why a reply must not go to ``topic``, a request's response topic, or ``None``: one that
    cannot be published to, a broker's own (``$SYS/…``), or a bridge's own topic. A reply
    carries its ``command``: on a ``cmd`` topic a bridge would carry it out again (this one, or
    another robot's), and on a ``state`` or ``events`` topic the fleet would take it for the
    robot's.

    >>> response_topic_problem("rovlink/rov-1/cmd/reply") is None
    True
    >>> response_topic_problem("rovlink/rov-2/cmd")
    "is a bridge's own topic (the command topic of robot 'rov-2')"
    """
    problem = publish_topic_problem(topic)
    if problem is not None:
        return problem
    if topic.startswith("$"):  # ($SYS/…, $share/…: MQTT leaves them to the broker)
        return "is a broker's own topic (it starts with '$')"
    parts = robot_of(topic)
    if parts is not None and parts[1] in _BRIDGE_TOPICS:
        what = "command" if parts[1] == "cmd" else parts[1]
        return f"is a bridge's own topic (the {what} topic of robot {parts[0]!r})"
    return None


def robot_of(topic: str) -> tuple[str, str] | None:
    """``(robot id, what)`` of a bridge topic, e.g. ``("rov-1", "state")``; else ``None``.

    >>> robot_of("rovlink/rov-1/state"), robot_of("other/x")
    (('rov-1', 'state'), None)
    """
    parts = topic.split("/", 2)
    if len(parts) != 3 or parts[0] != ROOT:
        return None
    return parts[1], parts[2]


@dataclass(frozen=True, slots=True)
class Topics:
    """The topic names of robot ``robot_id``.

    >>> Topics("rov-1").command_reply
    'rovlink/rov-1/cmd/reply'
    """

    robot_id: str

    def _topic(self, what: str) -> str:
        return f"{ROOT}/{self.robot_id}/{what}"

    @property
    def telemetry(self) -> str:
        """JSON readings at the chosen rate (QoS 0)."""
        return self._topic("telemetry")

    @property
    def state(self) -> str:
        """Retained JSON: online, lock, mode, set-points, link health (QoS 1); the last will."""
        return self._topic("state")

    @property
    def events(self) -> str:
        """JSON events: leak, failsafe, suspected reset, link (QoS 1)."""
        return self._topic("events")

    @property
    def command(self) -> str:
        """Commands in the console's words (QoS 1)."""
        return self._topic("cmd")

    @property
    def command_reply(self) -> str:
        """Where replies go when a command names no response topic of its own."""
        return self._topic("cmd/reply")
