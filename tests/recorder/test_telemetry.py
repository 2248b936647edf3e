"""The telemetry table follows the side effects of commands, as the controller applies them."""

from __future__ import annotations

from rovlink.protocol import Command, Response
from rovlink.recorder.telemetry import TelemetryState


def _state(*messages: Command | Response) -> dict[str, int | None]:
    state = TelemetryState()
    for message in messages:
        if isinstance(message, Command):
            state.observe_command(message)
        else:
            state.observe_response(message)
    return state.values


def test_leaving_direct_mode_ends_its_vertical_thrust_and_holds_the_depth_now() -> None:
    # P9: a change of mode sets vertical thrust 0; depth mode entered unlocked holds the depth.
    values = _state(
        Command("start"),
        Command("mvdirect", (1,)),
        Command("mvs", (-50,)),
        Response("qd", (42,)),
        Command("mvdirect", (0,)),
    )
    assert values["vertical_direct"] == 0
    assert values["vertical_thrust_percent"] == 0
    assert values["setpoint_cm"] == 42


def test_entering_direct_mode_ends_the_depth_target() -> None:
    values = _state(Command("start"), Command("mvd", (30,)), Command("mvdirect", (1,)))
    assert values["setpoint_cm"] is None
    assert values["vertical_thrust_percent"] == 0


def test_the_same_mode_again_changes_nothing() -> None:
    values = _state(Command("mvdirect", (1,)), Command("mvs", (-50,)), Command("mvdirect", (1,)))
    assert values["vertical_thrust_percent"] == -50


def test_depth_mode_entered_while_locked_has_no_target() -> None:
    values = _state(
        Command("stop"), Command("mvdirect", (1,)), Response("qd", (42,)), Command("mvdirect", (0,))
    )
    assert values["setpoint_cm"] is None


def test_stop_clears_every_set_point_and_start_unlocks_with_them_neutral() -> None:
    # P7: no depth target, no thrust, no horizontal power.
    moving = (Command("start"), Command("mvd", (30,)), Command("th", (90, 40)))
    for endings, locked in (((Command("stop"),), 1), ((Command("stop"), Command("start")), 0)):
        values = _state(*moving, *endings)
        assert values["locked"] == locked
        assert values["setpoint_cm"] is None
        assert values["thrust_power_percent"] == 0
        assert values["vertical_thrust_percent"] == 0


def test_start_while_unlocked_changes_nothing() -> None:
    # P7: the controller keeps its set-points; a plot showed the robot idle while it drove.
    values = _state(
        Command("start"), Command("th", (90, 40)), Command("mvd", (30,)), Command("start")
    )
    assert values["thrust_power_percent"] == 40
    assert values["setpoint_cm"] == 30


def test_commands_the_controller_drops_are_not_taken() -> None:
    # P7: motion while locked; P9: a command of the other vertical mode.
    locked = _state(Command("stop"), Command("mvd", (120,)), Command("th", (90, 40)))
    assert locked["setpoint_cm"] is None
    assert locked["thrust_power_percent"] == 0
    direct = _state(Command("start"), Command("mvdirect", (1,)), Command("mvd", (120,)))
    assert direct["setpoint_cm"] is None
    depth = _state(Command("start"), Command("mvdirect", (0,)), Command("mvs", (-50,)))
    assert depth["vertical_thrust_percent"] == 0
