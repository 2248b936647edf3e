"""Which frames the monitor's keys send, from the state as last sent and the latest depth."""

from __future__ import annotations

from rovlink.piloting import CommandedState
from rovlink.protocol import Command, Setting, VerticalMode, lookup, setting_command

__all__ = [
    "DEPTH_STEP_CM",
    "DIRECTION_STEP_DEG",
    "FIRST_TARGET_TEXT",
    "POWER_STEP_PERCENT",
    "NoDepthReadingError",
    "change_depth_target",
    "change_power",
    "turn",
]

DIRECTION_STEP_DEG = 15
POWER_STEP_PERCENT = 10
DEPTH_STEP_CM = 10

_MAX_POWER = lookup("th").arguments[1].maximum
_MAX_DEPTH_CM = lookup("mvd").arguments[0].maximum


def turn(state: CommandedState, step_deg: int) -> Command:
    """``th`` with the direction turned by ``step_deg`` (clockwise +) at the power as last sent.

    >>> turn(CommandedState(direction_deg=0, power_percent=30), -15)
    Command(name='th', values=(345, 30))
    """
    return Command("th", ((state.direction_deg + step_deg) % 360, state.power_percent))


def change_power(state: CommandedState, step_percent: int) -> Command:
    """``th`` with the power changed by ``step_percent`` (kept in 0–100), same direction.

    >>> change_power(CommandedState(direction_deg=90, power_percent=95), 10)
    Command(name='th', values=(90, 100))
    """
    power = min(max(state.power_percent + step_percent, 0), _MAX_POWER)
    return Command("th", (state.direction_deg, power))


#: Why a first depth target needs a reading of the depth now.
FIRST_TARGET_TEXT = "the first depth target is a step from the depth now"


class NoDepthReadingError(ValueError):
    """A first depth target asked for with no depth reading to step from."""


def change_depth_target(state: CommandedState, depth_cm: int | None, step_cm: int) -> list[Command]:
    """``mvd`` with the target moved by ``step_cm`` (+ deeper), after ``mvdirect 0`` unless depth
    mode was the last sent. With no target sent yet, the step is from the depth now
    (``depth_cm``); with no reading of it either, :class:`NoDepthReadingError` (a step from 0 cm
    would send a robot at 3 m up to 10 cm).

    >>> change_depth_target(CommandedState(), 57, DEPTH_STEP_CM)
    [Command(name='mvdirect', values=(0,)), Command(name='mvd', values=(60,))]
    """
    if not step_cm:
        raise ValueError("step_cm must not be 0")
    commands = []
    if state.vertical_mode is not VerticalMode.DEPTH:
        commands.append(setting_command(Setting.DIRECT_MODE, False))
    if state.target_depth_cm is not None and state.vertical_mode is VerticalMode.DEPTH:
        target_cm = state.target_depth_cm + step_cm
    else:  # the next point of the step grid beyond the depth now, in the step's direction
        if depth_cm is None:
            raise NoDepthReadingError(f"no depth reading yet: {FIRST_TARGET_TEXT}")
        now_cm = depth_cm
        size_cm = abs(step_cm)
        if step_cm > 0:
            target_cm = (now_cm // size_cm + 1) * size_cm
        else:
            target_cm = -(-now_cm // size_cm) * size_cm - size_cm
    commands.append(Command("mvd", (min(max(target_cm, 0), _MAX_DEPTH_CM),)))
    return commands
