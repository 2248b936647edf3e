"""Which frames the monitor's keys send."""

from __future__ import annotations

import pytest

from rovlink.monitor.controls import (
    NoDepthReadingError,
    change_depth_target,
    change_power,
    turn,
)
from rovlink.piloting import CommandedState
from rovlink.protocol import Command, VerticalMode


def test_turning_wraps_around_and_keeps_the_power() -> None:
    state = CommandedState(direction_deg=350, power_percent=40)
    assert turn(state, 15) == Command("th", (5, 40))
    assert turn(CommandedState(), -15) == Command("th", (345, 0))


def test_power_stays_in_range() -> None:
    assert change_power(CommandedState(power_percent=5), -10) == Command("th", (0, 0))
    assert change_power(CommandedState(direction_deg=90, power_percent=100), 10) == Command(
        "th", (90, 100)
    )


@pytest.mark.parametrize(
    ("depth_cm", "step_cm", "target_cm"),
    [
        (0, -10, 0),
        (57, 10, 60),
        (57, -10, 50),
        (60, 10, 70),
        (60, -10, 50),
        (9995, 10, 9999),
    ],
)
def test_the_first_target_is_the_next_step_from_the_depth_now(
    depth_cm: int | None, step_cm: int, target_cm: int
) -> None:
    assert change_depth_target(CommandedState(), depth_cm, step_cm) == [
        Command("mvdirect", (0,)),
        Command("mvd", (target_cm,)),
    ]


def test_with_no_depth_reading_the_first_target_is_refused() -> None:
    # (A step from 0 cm would send a robot at 3 m up to 10 cm.)
    with pytest.raises(NoDepthReadingError, match="no depth reading yet"):
        change_depth_target(CommandedState(), None, 10)
    state = CommandedState(vertical_mode=VerticalMode.DEPTH, target_depth_cm=30)
    assert change_depth_target(state, None, 10) == [Command("mvd", (40,))]  # (from the target)


def test_later_steps_move_the_target_as_last_sent() -> None:
    state = CommandedState(vertical_mode=VerticalMode.DEPTH, target_depth_cm=30)
    assert change_depth_target(state, 12, -10) == [Command("mvd", (20,))]


def test_direct_mode_as_last_sent_is_left_for_depth_mode_first() -> None:
    state = CommandedState(vertical_mode=VerticalMode.DIRECT, target_depth_cm=None)
    assert change_depth_target(state, 40, 10)[0] == Command("mvdirect", (0,))
    with pytest.raises(ValueError, match="step_cm"):
        change_depth_target(state, 40, 0)
