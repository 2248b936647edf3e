"""P7: locked after reset and on #stop!; #start! unlocks with neutral set-points."""

from __future__ import annotations

import pytest

from rovlink.protocol import VerticalMode
from tests.controller.controller_rig import Rig

MOTION = [b"#mvd.100!", b"#th.0.100!", b"#h+!", b"#h-!"]


def test_motors_are_locked_after_reset(rig: Rig) -> None:
    assert rig.controller.locked
    rig.tick()
    assert set(rig.thrusters.duties) == {0}
    assert rig.claw.direction == 0


@pytest.mark.parametrize("frame", MOTION)
def test_motion_commands_are_dropped_while_locked(rig: Rig, frame: bytes) -> None:
    before = rig.controller.state()
    rig.send(frame)
    rig.tick(10)
    assert rig.controller.state() == before
    assert set(rig.thrusters.duties) == {0}
    assert rig.claw.history == [(0.0, 0)]


def test_mvs_is_dropped_while_locked(rig: Rig) -> None:
    rig.send(b"#mvdirect.1!#mvs.+100!")
    rig.tick()
    assert rig.controller.state().vertical_thrust_percent == 0
    assert set(rig.thrusters.duties) == {0}


def test_settings_modes_calibration_checksum_debug_and_queries_work_while_locked(
    rig: Rig,
) -> None:
    rig.send(b"#mgmp.100!#mvpdp.5!#mvpdi.6!#mvpidd.7!#mvdirect.1!#sdz.30!#sdk.300!#debug1!")
    rig.controller.read_output()
    state = rig.controller.state()
    assert state.locked
    assert (state.max_pwm, state.gains, state.vertical_mode) == (100, (5, 6, 7), "direct")
    assert (state.depth_zero_raw, state.depth_k, state.debug_enabled) == (30, 300, True)
    rig.send(b"#crcon!")
    assert rig.controller.state().checksum_enabled
    assert rig.send(b"#debug0!#crcoff!#qr!").endswith(b"$qr.20!")


def test_start_unlocks_with_neutral_set_points(rig: Rig) -> None:
    rig.send(b"#start!")
    state = rig.controller.state()
    assert not state.locked
    assert (state.vertical_thrust_percent, state.target_depth_cm) == (0, None)
    assert (state.power_percent, state.claw_direction) == (0, 0)
    rig.tick()
    assert set(rig.thrusters.duties) == {0}


def test_stop_zeroes_every_output_at_once_and_clears_the_set_points(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.0.100!#mvdirect.1!#mvs.-100!#h+!")
    armed_rig.tick()
    assert all(armed_rig.thrusters.duties)
    assert armed_rig.claw.direction == 1
    writes = armed_rig.thrusters.writes
    armed_rig.send(b"#stop!")
    # No tick needed: the outputs are written inside receive().
    assert armed_rig.thrusters.writes == writes + 1
    assert set(armed_rig.thrusters.duties) == {0}
    assert armed_rig.claw.direction == 0
    state = armed_rig.controller.state()
    assert state.locked
    assert (state.vertical_thrust_percent, state.target_depth_cm) == (0, None)
    assert state.power_percent == 0
    assert state.claw_direction == 0


def test_after_stop_and_start_the_old_set_points_are_gone(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.0.100!#mvd.300!#stop!#start!")
    armed_rig.tick(20)
    assert set(armed_rig.thrusters.duties) == {0}
    assert armed_rig.controller.state().target_depth_cm is None


def test_stop_keeps_the_vertical_mode_and_settings(armed_rig: Rig) -> None:
    armed_rig.send(b"#mgmp.77!#mvdirect.1!#stop!")
    state = armed_rig.controller.state()
    assert (state.max_pwm, state.vertical_mode) == (77, VerticalMode.DIRECT)


def test_start_while_unlocked_changes_nothing(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.90.30!")
    before = armed_rig.controller.state()
    armed_rig.send(b"#start!")
    assert armed_rig.controller.state() == before


def test_reset_locks_again(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.0.100!")
    armed_rig.tick()
    armed_rig.controller.reset()
    assert armed_rig.controller.locked
    assert set(armed_rig.thrusters.duties) == {0}
