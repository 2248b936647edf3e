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

from rovlink.protocol import (
    COMMANDS,
    Command,
    Kind,
    Response,
    Setting,
    Spec,
    VerticalMode,
    lookup,
)
from rovlink.recorder.entries import TELEMETRY_FIELDS

__all__ = ["COLUMN_RANGES", "COMMAND_COLUMNS", "RESPONSE_COLUMNS", "TelemetryState"]

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


def _column_ranges() -> dict[str, tuple[int, int]]:
    """Each column's range, from the argument of the command table it is taken from (the lock
    is 0 or 1)."""
    ranges = {"locked": (0, 1)}
    for kind, table in ((Kind.RESPONSE, RESPONSE_COLUMNS), (Kind.COMMAND, COMMAND_COLUMNS)):
        for name, columns in table.items():
            for column, argument in zip(columns, lookup(name, kind).arguments, strict=True):
                ranges[column] = (argument.minimum, argument.maximum)
    return ranges


#: Column → its least and greatest value: a recording with a value outside is damaged.
COLUMN_RANGES: dict[str, tuple[int, int]] = _column_ranges()


def _columns(specs: Iterable[Spec]) -> tuple[str, ...]:
    return tuple(column for spec in specs for column in COMMAND_COLUMNS.get(spec.name, ()))


#: The columns of the motion commands (P7: ``stop`` and ``start`` clear them), and of the
#: commands of each vertical mode (P9: a change of mode resets them), from the command table.
_MOTION_COLUMNS = _columns(spec for spec in COMMANDS if spec.motion)
_MODE_COLUMNS = {
    mode: _columns(spec for spec in COMMANDS if spec.mode is mode) for mode in VerticalMode
}
#: A cleared set-point is 0, but for a target, which is then none (P7: "no depth target").
_NO_TARGET = frozenset(_MODE_COLUMNS[VerticalMode.DEPTH])


def _cleared(column: str) -> int | None:
    return None if column in _NO_TARGET else 0


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
        """Take a command's effect, as the controller takes it; whether any column changed."""
        setting = command.setting
        values = self.values
        if setting is not None and setting[0] is Setting.LOCKED:
            if not setting[1] and values["locked"] == 0:
                return False  # ``start`` while unlocked changes nothing (P7)
            # ``stop`` locks with every set-point cleared, ``start`` unlocks with them neutral.
            cleared = [(column, _cleared(column)) for column in _MOTION_COLUMNS]
            return self._set([("locked", int(setting[1])), *cleared])
        if setting is not None and setting[0] is Setting.DIRECT_MODE:
            return self._change_mode(setting[1])
        columns = COMMAND_COLUMNS.get(command.name)
        if columns is None or self._dropped(command):
            return False
        return self._set(zip(columns, command.values, strict=False))

    def _dropped(self, command: Command) -> bool:
        """Whether the controller drops ``command`` in the state known: a motion command while
        locked (P7), one of the other vertical mode (P9). An unknown state drops nothing."""
        spec = command.spec
        values = self.values
        if spec.motion and values["locked"] == 1:
            return True
        direct = values["vertical_direct"]
        return (
            spec.mode is not None
            and direct is not None
            and ((spec.mode is VerticalMode.DIRECT) != bool(direct))
        )

    def _change_mode(self, direct: bool) -> bool:
        """``mvdirect``: a change of vertical mode ends the set-points of the mode left and
        starts the new one's afresh (P9): direct mode at 0 thrust, depth mode holding the depth
        now if unlocked (the last known), else with no target. The same mode changes nothing."""
        values = self.values
        if values["vertical_direct"] == int(direct):
            return False
        entered = VerticalMode.DIRECT if direct else VerticalMode.DEPTH
        pairs: list[tuple[str, int | None]] = [("vertical_direct", int(direct))]
        for mode, columns in _MODE_COLUMNS.items():
            for column in columns:
                holds = mode is entered is VerticalMode.DEPTH and values["locked"] == 0
                pairs.append((column, values["depth_cm"] if holds else _cleared(column)))
        return self._set(pairs)

    def _set(self, pairs: Iterable[tuple[str, int | None]]) -> bool:
        values = self.values
        changed = False
        for column, value in pairs:
            if values[column] != value:
                values[column] = value
                changed = True
        return changed
