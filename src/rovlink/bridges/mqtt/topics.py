"""The topics of one robot: ``rovlink/ID/`` + ``telemetry``, ``state``, ``events``, ``cmd``,
``cmd/reply``."""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["ROOT", "Topics", "check_robot_id", "robot_of"]

#: Every topic of the bridges is under this.
ROOT = "rovlink"
_ROBOT_ID = re.compile(r"[A-Za-z0-9_.-]{1,64}")


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
