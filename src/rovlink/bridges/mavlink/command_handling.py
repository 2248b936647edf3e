"""MAVLink commands (COMMAND_LONG, COMMAND_INT, SET_MODE) to the vehicle's actions.

Every command gets a COMMAND_ACK; one the bridge does not know is answered
MAV_RESULT_UNSUPPORTED, never ignored. A command it knows asked for something it cannot do (a
flight mode it has not, a message it does not send) is MAV_RESULT_DENIED, as MAVLink has it
("supported, but invalid parameters"): UNSUPPORTED would tell the ground station that the
command itself is unknown, and ground stations stop using a command they were told so.
"""

from __future__ import annotations

import math
from enum import IntEnum
from typing import Protocol

from rovlink.bridges.mavlink.modes import FlightMode

__all__ = ["MAV_CMD", "Result", "VehicleActions", "handle_command", "mode_result"]


class Result(IntEnum):
    """MAV_RESULT."""

    ACCEPTED = 0
    TEMPORARILY_REJECTED = 1
    DENIED = 2
    UNSUPPORTED = 3
    FAILED = 4


class MAV_CMD(IntEnum):  # noqa: N801 - MAVLink's own name
    """The MAV_CMD values the bridge carries out."""

    DO_SET_MODE = 176
    DO_GRIPPER = 211
    COMPONENT_ARM_DISARM = 400
    GET_MESSAGE_INTERVAL = 510
    SET_MESSAGE_INTERVAL = 511
    REQUEST_MESSAGE = 512
    REQUEST_AUTOPILOT_CAPABILITIES = 520


_CUSTOM_MODE_ENABLED = 1  # MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
_GRIPPER_RELEASE = 0  # GRIPPER_ACTION_RELEASE: open
_GRIPPER_GRAB = 1  # GRIPPER_ACTION_GRAB: close
_AUTOPILOT_VERSION = 148  # message id
#: What MESSAGE_INTERVAL can carry: a uint16 message id and an int32 interval, µs (about 35
#: min). Anything beyond is denied: accepted, the GET_MESSAGE_INTERVAL after it went unanswered.
_LAST_MESSAGE_ID = 0xFFFF
_LONGEST_INTERVAL_US = 0x7FFFFFFF


class VehicleActions(Protocol):
    """What the commands act on (the bridge)."""

    async def arm(self) -> Result:
        """``#start!``."""

    async def disarm(self, reason: str) -> Result:
        """``#stop!``: always accepted."""

    async def set_mode(self, mode: FlightMode) -> Result:
        """Switch the vertical mode."""

    async def gripper(self, *, close: bool) -> Result:
        """``#h-!`` (close) or ``#h+!`` (open)."""

    def request_message(self, message_id: int) -> Result:
        """Send one message now."""

    def set_message_interval(self, message_id: int, interval_us: float) -> Result:
        """Send a message at an interval (−1: not at all, 0: its default)."""

    def get_message_interval(self, message_id: int) -> Result:
        """Say a message's interval (MESSAGE_INTERVAL)."""


def _whole(value: float) -> int | None:
    """A parameter that must be a whole number, or ``None`` (NaN, infinite, fractional)."""
    if not math.isfinite(value) or value != round(value):
        return None
    return round(value)


async def mode_result(actions: VehicleActions, base_mode: float, custom_mode: float) -> Result:
    """DO_SET_MODE or SET_MODE: a custom mode the bridge serves, else denied."""
    base, custom = _whole(base_mode), _whole(custom_mode)
    if base is None or custom is None or not base & _CUSTOM_MODE_ENABLED:
        return Result.DENIED
    try:
        mode = FlightMode(custom)
    except ValueError:
        return Result.DENIED
    return await actions.set_mode(mode)


async def handle_command(actions: VehicleActions, command: int, params: list[float]) -> Result:
    """Carry out MAV_CMD ``command`` with its seven parameters; its MAV_RESULT."""
    p1, p2 = params[0], params[1]
    if command == MAV_CMD.COMPONENT_ARM_DISARM:
        if p1 == 1:
            return await actions.arm()
        if p1 == 0:
            return await actions.disarm("disarmed by the ground station")
        return Result.DENIED
    if command == MAV_CMD.DO_SET_MODE:
        return await mode_result(actions, p1, p2)
    if command == MAV_CMD.DO_GRIPPER:
        if p2 not in (_GRIPPER_RELEASE, _GRIPPER_GRAB):
            return Result.DENIED
        return await actions.gripper(close=p2 == _GRIPPER_GRAB)
    if command == MAV_CMD.REQUEST_AUTOPILOT_CAPABILITIES:
        return actions.request_message(_AUTOPILOT_VERSION)
    if command in (
        MAV_CMD.REQUEST_MESSAGE,
        MAV_CMD.SET_MESSAGE_INTERVAL,
        MAV_CMD.GET_MESSAGE_INTERVAL,
    ):
        message_id = _whole(p1)
        if message_id is None or not 0 <= message_id <= _LAST_MESSAGE_ID:
            return Result.DENIED
        if command == MAV_CMD.SET_MESSAGE_INTERVAL and not p2 <= _LONGEST_INTERVAL_US:
            return Result.DENIED  # (NaN too)
        if command == MAV_CMD.REQUEST_MESSAGE:
            return actions.request_message(message_id)
        if command == MAV_CMD.GET_MESSAGE_INTERVAL:
            return actions.get_message_interval(message_id)
        return actions.set_message_interval(message_id, p2)
    return Result.UNSUPPORTED
