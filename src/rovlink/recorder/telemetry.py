"""The telemetry table: the robot's state as the host sees it, from the frames on the link.

Replies update the sensor columns; commands update the set-point, mode, lock and thrust
columns. Each column is keyed by a frame and an argument of the command table, so a renamed
argument fails the test that checks the keys rather than silently emptying a column.

>>> from rovlink.protocol import Command, Response
>>> state = TelemetryState()
>>> state.observe_command(Command("mvd", (120,)))
True
>>> state.observe_response(Response("qd", (95,)))
True
>>> state.values["depth_cm"], state.values["setpoint_cm"]
(95, 120)
"""

from __future__ import annotations

from collections.abc import Iterable

from rovlink.protocol import Command, Response
from rovlink.recorder.entries import TELEMETRY_FIELDS

__all__ = ["COMMAND_COLUMNS", "RESPONSE_COLUMNS", "TelemetryState"]

#: Response name → the column of each of its values.
RESPONSE_COLUMNS: dict[str, tuple[str, ...]] = {
    "qd": ("depth_cm",),
    "qr": ("pressure_raw",),
    "q.l": ("leak",),
    "qro": ("roll_deg",),
    "qpi": ("pitch_deg",),
    "qhe": ("heading_deg",),
}

#: Command name → the column of each of its values.
COMMAND_COLUMNS: dict[str, tuple[str, ...]] = {
    "mvd": ("setpoint_cm",),
    "mvs": ("vertical_thrust_percent",),
    "th": ("thrust_direction_deg", "thrust_power_percent"),
    "mvdirect": ("vertical_direct",),
}

# ``start`` unlocks with neutral set-points and ``stop`` locks with the motors off (P7): the
# thrust columns follow, so a plot never shows thrust the controller is not applying.
_NEUTRAL = {"vertical_thrust_percent": 0, "thrust_power_percent": 0}


class TelemetryState:
    """The last known value of every telemetry column (``None`` until first seen)."""

    def __init__(self) -> None:
        self.values: dict[str, int | None] = dict.fromkeys(TELEMETRY_FIELDS)

    def observe_response(self, response: Response) -> bool:
        """Take a reply's values; whether any column changed."""
        columns = RESPONSE_COLUMNS.get(response.name)
        if columns is None:
            return False
        return self._set(zip(columns, response.values, strict=False))

    def observe_command(self, command: Command) -> bool:
        """Take a command's effect; whether any column changed."""
        name = command.name
        if name == "start":
            return self._set([("locked", 0), *_NEUTRAL.items()])
        if name == "stop":
            return self._set([("locked", 1), *_NEUTRAL.items()])
        columns = COMMAND_COLUMNS.get(name)
        if columns is None:
            return False
        return self._set(zip(columns, command.values, strict=False))

    def _set(self, pairs: Iterable[tuple[str, int]]) -> bool:
        values = self.values
        changed = False
        for column, value in pairs:
            if values[column] != value:
                values[column] = value
                changed = True
        return changed
