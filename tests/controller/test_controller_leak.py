"""P14: the latched leak flag and the configurable leak action."""

from __future__ import annotations

from rovlink.controller import LeakAction
from rovlink.protocol import VerticalMode
from tests.controller.controller_rig import Rig, make_rig


def test_no_leak_after_reset(rig: Rig) -> None:
    assert rig.send(b"#q.l!") == b"$q.l.0!"


def test_a_leak_pulse_latches_until_slreset(rig: Rig) -> None:
    rig.leak.pulse()
    rig.tick()
    assert rig.send(b"#q.l!") == b"$q.l.1!"
    rig.run(10.0)  # the pulse is long over
    assert rig.send(b"#q.l!") == b"$q.l.1!"
    rig.send(b"#slreset!")
    assert rig.send(b"#q.l!") == b"$q.l.0!"


def test_a_leak_still_present_after_slreset_latches_again(rig: Rig) -> None:
    rig.leak.pulse()
    rig.tick()
    rig.send(b"#slreset!")
    rig.leak.pulse()
    rig.tick()
    assert rig.send(b"#q.l!") == b"$q.l.1!"


def test_leak_action_none_only_reports(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.0.50!")
    armed_rig.leak.pulse()
    armed_rig.tick()
    assert not armed_rig.controller.locked
    assert armed_rig.horizontal_duties == (128, 128, 128, 128)


def test_leak_action_stop_acts_as_stop() -> None:
    rig = make_rig(leak_action=LeakAction.STOP, watchdog_s=0.0)
    rig.send(b"#debug1!#start!#th.0.50!")
    rig.tick()
    rig.leak.pulse()
    output = rig.tick()
    assert rig.controller.locked
    assert set(rig.thrusters.duties) == {0}
    assert b"leak detected, action stop" in output
    assert rig.send(b"#q.l!") == b"$q.l.1!"


def test_leak_action_surface_goes_up_at_full_thrust_and_stays_unlocked() -> None:
    rig = make_rig(leak_action=LeakAction.SURFACE, watchdog_s=0.0)
    rig.send(b"#start!#mvd.500!#th.90.80!")
    rig.set_depth_cm(500)
    rig.tick()
    rig.leak.pulse()
    rig.tick()
    state = rig.controller.state()
    assert not state.locked
    assert (state.vertical_mode, state.vertical_thrust_percent) == (VerticalMode.DIRECT, 100)
    assert rig.thrusters.duties == (0, 0, 0, 0, 255, 255)


def test_leak_action_surface_never_moves_a_locked_robot() -> None:
    rig = make_rig(leak_action=LeakAction.SURFACE)
    rig.leak.pulse()
    rig.tick(5)
    assert rig.controller.locked
    assert set(rig.thrusters.duties) == {0}
    assert rig.send(b"#q.l!") == b"$q.l.1!"


def test_a_started_robot_is_stopped_again_by_the_next_leak_while_latched() -> None:
    rig = make_rig(leak_action=LeakAction.STOP, watchdog_s=0.0)
    rig.leak.pulse()
    rig.tick()
    rig.send(b"#start!#th.0.50!")  # the operator takes over, the latch still set
    rig.tick(5)
    assert not rig.controller.locked  # the latch alone does not stop it ...
    rig.leak.pulse()
    rig.tick()
    assert rig.controller.locked  # ... a new leak does
    assert set(rig.thrusters.duties) == {0}


def test_surface_action_is_taken_again_by_the_next_leak_while_latched() -> None:
    rig = make_rig(leak_action=LeakAction.SURFACE, watchdog_s=0.0)
    rig.send(b"#start!")
    rig.leak.pulse()
    rig.tick()
    rig.send(b"#mvdirect.0!#mvd.500!#th.90.80!")  # the operator dives again, latch still set
    rig.tick()
    assert rig.controller.state().vertical_mode is VerticalMode.DEPTH
    rig.leak.pulse()
    rig.tick()
    state = rig.controller.state()
    assert (state.vertical_mode, state.vertical_thrust_percent) == (VerticalMode.DIRECT, 100)
    assert state.power_percent == 0


def test_leak_action_stop_clears_the_set_points_as_stop_does() -> None:
    rig = make_rig(leak_action=LeakAction.STOP, watchdog_s=0.0)
    rig.send(b"#start!#mvd.300!#th.90.50!#h+!")
    rig.leak.pulse()
    rig.tick()
    state = rig.controller.state()
    assert (state.target_depth_cm, state.power_percent) == (None, 0)
    assert rig.claw.direction == 0
    rig.send(b"#start!")  # unlocking again resumes nothing
    rig.tick(10)
    assert set(rig.thrusters.duties) == {0}
