"""Every robot on a broker, from the bridges' topics: what ``rovlink fleet`` shows.

Fed with each message of ``rovlink/+/state``, ``telemetry`` and ``events``; a payload that is
not a bridge's JSON is counted and ignored (any program may publish under ``rovlink/``). Every
text here comes from the broker: whoever shows it must show it as text, not obey it.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from rovlink.bridges.mqtt.topics import robot_of

__all__ = ["SILENT_AFTER_S", "FleetView", "RobotRow"]

#: An online robot whose bridge has said nothing for this long is shown as silent.
SILENT_AFTER_S = 10.0


@dataclass(slots=True)
class RobotRow:
    """One robot as the broker tells it."""

    robot: str
    online: bool | None = None
    offline_reason: str | None = None
    depth_cm: int | None = None
    #: ``None`` until a message tells (an offline state, the last will, does not).
    leak: bool | None = None
    link: str | None = None
    lock: str | None = None
    mode: str | None = None
    last_event: str | None = None
    last_heard_s: float | None = None
    #: What is wrong with the last state, if it is not a bridge's (its presence is not guessed).
    state_problem: str | None = None
    #: Its bridge drives rovlink's simulator, not a robot (its state says ``"simulated": true``).
    simulated: bool = False

    def presence(self, now_s: float) -> str:
        """``online``, ``silent`` (online, but quiet too long), ``offline``, ``malformed`` (the
        last state did not say) or ``unknown``."""
        if self.state_problem is not None:
            return "malformed"
        if self.online is None:
            return "unknown"
        if not self.online:
            return "offline"
        if self.last_heard_s is not None and now_s - self.last_heard_s > SILENT_AFTER_S:
            return "silent"
        return "online"


class FleetView:
    """The robots seen so far, updated message by message.

    >>> view = FleetView()
    >>> view.apply("rovlink/rov-1/state", b'{"online": true, "lock": "locked"}', now_s=0.0)
    True
    >>> view.apply("rovlink/rov-1/telemetry", b'{"depth_cm": 120, "leak": false}', now_s=0.1)
    True
    >>> row = view.rows()[0]
    >>> row.robot, row.presence(now_s=1.0), row.depth_cm, row.lock
    ('rov-1', 'online', 120, 'locked')
    """

    def __init__(self) -> None:
        self._robots: dict[str, RobotRow] = {}
        #: Messages under ``rovlink/`` that were not a bridge's JSON.
        self.ignored = 0

    def rows(self) -> list[RobotRow]:
        """Every robot, by id."""
        return [self._robots[robot] for robot in sorted(self._robots)]

    def apply(
        self,
        topic: str,
        payload: bytes,
        now_s: float,
        *,
        retained_wall_now_s: float | None = None,
    ) -> bool:
        """Take one message; whether it was a bridge's.

        ``retained_wall_now_s`` (Unix time now, s) marks a message the broker kept (retained),
        handed over on subscribing however old it is: a state then counts as heard when its
        ``at`` says it was published, not now. A broker that lost power restores the states it
        persisted, "online" for a robot whose bridge went with it, and no last will follows.
        """
        where = robot_of(topic)
        if where is None:
            self.ignored += 1
            return False
        robot, what = where
        try:
            data = json.loads(payload)
        except (ValueError, RecursionError):
            # Not UTF-8, not JSON, an integer of more digits than Python converts, or nested
            # deeper than the parser goes: anyone may publish it (retained, at every start).
            data = None
        if not isinstance(data, dict) or what not in ("state", "telemetry", "events"):
            self.ignored += 1
            return False
        row = self._robots.setdefault(robot, RobotRow(robot))
        heard_s = now_s - _age_s(data, retained_wall_now_s)
        if row.last_heard_s is None or heard_s > row.last_heard_s:  # (a retained one is older)
            row.last_heard_s = heard_s
        if what == "state":
            self._state(row, data)
        elif what == "telemetry":
            row.depth_cm = _integer(data.get("depth_cm"), row.depth_cm)
            row.leak = _leak(data.get("leak"), row.leak)
            if row.online is None:
                row.online = True
        else:
            row.last_event = f"{data.get('event', '?')}: {data.get('detail', '')}".strip()
            if data.get("event") == "leak":
                row.leak = True
        return True

    @staticmethod
    def _state(row: RobotRow, data: dict[str, Any]) -> None:
        online = data.get("online")
        if not isinstance(online, bool):  # "false" is not false: show it, do not guess
            row.state_problem = f'"online" is {json.dumps(online)}, not true or false'
            return
        row.state_problem = None
        row.online = online
        if not online:
            reason = data.get("reason", "")
            row.offline_reason = reason if isinstance(reason, str) else json.dumps(reason)
            return
        row.offline_reason = None
        row.simulated = data.get("simulated") is True
        row.depth_cm = _integer(data.get("depth_cm"), row.depth_cm)
        row.leak = _leak(data.get("leak"), row.leak)
        row.lock = data.get("lock") if isinstance(data.get("lock"), str) else row.lock
        row.mode = data.get("mode") if isinstance(data.get("mode"), str) else row.mode
        link = data.get("link")
        if isinstance(link, dict) and isinstance(link.get("status"), str):
            row.link = link["status"]


def _age_s(data: dict[str, Any], retained_wall_now_s: float | None) -> float:
    """How long ago a retained message was published, by its ``at`` (0 if it does not say, or
    if its clock is ahead of this one's: a bridge is not called silent for its clock)."""
    at_s = data.get("at")
    if retained_wall_now_s is None or isinstance(at_s, bool) or not isinstance(at_s, (int, float)):
        return 0.0
    try:
        age_s = retained_wall_now_s - float(at_s)
    except OverflowError:  # (a JSON integer of hundreds of digits)
        return 0.0
    return age_s if math.isfinite(age_s) and age_s > 0 else 0.0


def _leak(value: object, default: bool | None) -> bool | None:
    """A message's ``leak``: JSON true or false; any other value that is set counts as a leak
    (a warning too many rather than a leak missed); none leaves ``default``."""
    if isinstance(value, bool):
        return value
    return True if value else default


def _integer(value: object, default: int | None) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) else default
