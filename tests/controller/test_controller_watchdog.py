"""P17: the link-loss failsafe."""

from __future__ import annotations

import pytest

from tests.controller.controller_rig import TICK_S, Rig, make_rig


def _trip_time_s(rig: Rig, limit_s: float = 10.0) -> float:
    while not rig.controller.locked:
        rig.tick()
        if rig.clock.time_s > limit_s:
            pytest.fail("the watchdog never tripped")
    return rig.clock.time_s


@pytest.mark.parametrize("watchdog_s", [2.0, 0.5, 1.234])
def test_the_watchdog_trips_at_its_timeout_to_within_one_tick(watchdog_s: float) -> None:
    rig = make_rig(watchdog_s=watchdog_s)
    rig.tick(7)
    rig.send(b"#start!#th.0.100!")
    last_frame_s = rig.clock.time_s
    trip_s = _trip_time_s(rig)
    assert watchdog_s - 1e-6 <= trip_s - last_frame_s <= watchdog_s + TICK_S + 1e-6
    assert set(rig.thrusters.duties) == {0}
    assert rig.controller.state().power_percent == 0


def test_any_valid_frame_keeps_the_link_alive() -> None:
    rig = make_rig()
    rig.send(b"#start!#th.0.100!")
    for frame in [b"#qd!", b"#qhe!", b"#mgmp.255!", b"#mvs.+1!"]:  # mvs is dropped, still valid
        rig.run(1.5)
        rig.send(frame)
    rig.run(1.5)
    assert not rig.controller.locked


def test_another_line_does_not_keep_the_driving_line_alive() -> None:
    # A host drives on one line, a monitor polls on another (a TCP client and the PTY): when
    # the driving host dies, the monitor's queries must not keep its motion running.
    rig = make_rig(watchdog_s=0.5)
    rig.controller.receive(b"#start!#th.0.100!", "station")
    last_frame_s = rig.clock.time_s
    while not rig.controller.locked and rig.clock.time_s < 5.0:
        rig.controller.receive(b"#qsa!#mgmp.255!", "monitor")
        rig.tick()
    assert rig.controller.locked
    assert 0.5 - 1e-6 <= rig.clock.time_s - last_frame_s <= 0.5 + TICK_S + 1e-6
    assert set(rig.thrusters.duties) == {0}


def test_the_line_that_drives_last_is_the_one_that_must_stay_alive() -> None:
    rig = make_rig(watchdog_s=0.5)
    rig.controller.receive(b"#start!", "first")
    rig.run(0.3)
    rig.controller.receive(b"#th.0.50!", "second")  # the second host takes over the driving
    for _ in range(5):  # the first goes quiet; the second keeps its link alive with queries
        rig.run(0.3)
        rig.controller.receive(b"#qd!", "second")
    assert not rig.controller.locked
    rig.controller.receive(b"#th.0.60!", "first")  # back to the first, which then goes quiet
    rig.run(0.3)
    rig.controller.receive(b"#qd!", "second")
    rig.run(0.3)
    assert rig.controller.locked


def test_bad_frames_and_replies_do_not_keep_the_link_alive() -> None:
    rig = make_rig()
    rig.send(b"#start!")
    start_s = rig.clock.time_s
    for _ in range(3):
        rig.run(0.5)
        rig.send(b"#qx!#mgmp.300!$qd.1!noise\r\n")
    assert 2.0 - 1e-6 <= _trip_time_s(rig) - start_s <= 2.0 + TICK_S + 1e-6


def test_the_watchdog_only_acts_while_unlocked(debug_rig: Rig) -> None:
    output = debug_rig.run(5.0)
    assert b"failsafe" not in output
    assert debug_rig.controller.locked


def test_zero_disables_the_watchdog() -> None:
    rig = make_rig(watchdog_s=0.0)
    rig.send(b"#start!")
    rig.run(60.0)
    assert not rig.controller.locked


def test_after_a_trip_start_rearms() -> None:
    rig = make_rig()
    rig.send(b"#start!")
    _trip_time_s(rig)
    rig.send(b"#start!#th.0.10!")
    rig.run(1.0)
    assert not rig.controller.locked
    assert rig.horizontal_duties == (26, 26, 26, 26)
