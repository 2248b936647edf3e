"""P9 (vertical modes), P10 (the depth PID through frames), P18 (the mvpdd alias)."""

from __future__ import annotations

import pytest

from rovlink.controller import ControllerConfig, DepthPidConfig
from rovlink.protocol import VerticalMode
from tests.controller.controller_rig import Rig, make_rig


def test_depth_mode_after_reset(rig: Rig) -> None:
    assert rig.controller.state().vertical_mode is VerticalMode.DEPTH


def test_direct_mode_sets_vertical_thrust(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvdirect.1!#mvs.+100!")
    armed_rig.tick()
    assert armed_rig.vertical_duties == (255, 255)
    armed_rig.send(b"#mvs.-50!")
    armed_rig.tick()
    assert armed_rig.vertical_duties == (-128, -128)


def test_mvs_is_dropped_in_depth_mode_and_mvd_in_direct_mode(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvs.+100!")
    assert armed_rig.controller.state().vertical_thrust_percent == 0
    armed_rig.send(b"#mvdirect.1!#mvd.300!")
    assert armed_rig.controller.state().target_depth_cm is None


def test_entering_depth_mode_while_unlocked_holds_the_current_depth(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvdirect.1!#mvs.-100!")
    armed_rig.set_depth_cm(236)
    armed_rig.tick()
    armed_rig.send(b"#mvdirect.0!")
    state = armed_rig.controller.state()
    assert (state.vertical_mode, state.target_depth_cm) == (VerticalMode.DEPTH, 236)
    assert state.vertical_thrust_percent == 0


def test_entering_depth_mode_while_locked_sets_no_target(rig: Rig) -> None:
    rig.set_depth_cm(100)
    rig.send(b"#mvdirect.1!#mvdirect.0!")
    assert rig.controller.state().target_depth_cm is None


def test_entering_direct_mode_sets_vertical_thrust_zero(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvd.500!")
    armed_rig.tick()
    assert armed_rig.vertical_duties[0] < 0  # diving
    armed_rig.send(b"#mvdirect.1!")
    armed_rig.tick()
    assert armed_rig.vertical_duties == (0, 0)
    assert armed_rig.controller.state().target_depth_cm is None


def test_depth_mode_without_a_target_gives_no_vertical_thrust(armed_rig: Rig) -> None:
    armed_rig.set_depth_cm(300)
    armed_rig.tick(100)
    assert armed_rig.vertical_duties == (0, 0)


def test_the_pid_thrusts_down_when_too_shallow_and_up_when_too_deep(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvd.100!")
    armed_rig.tick()
    assert armed_rig.vertical_duties[0] < 0
    armed_rig.set_depth_cm(200)
    armed_rig.tick(50)
    assert armed_rig.vertical_duties[0] > 0


def test_gains_are_scaled_by_the_configuration(armed_rig: Rig) -> None:
    # P only: kp 40 × 0.05 %/cm = 2 % per cm of error.
    armed_rig.send(b"#mvpdi.0!#mvpidd.0!#mvpdp.40!#mvd.100!")
    armed_rig.set_depth_cm(80)
    armed_rig.tick()
    assert armed_rig.vertical_duties == (-102, -102)  # 40 % down of 255
    armed_rig.send(b"#mvpdp.10!")
    armed_rig.tick()
    assert armed_rig.vertical_duties == (-26, -26)  # 10 %


def test_other_scales_give_other_physical_gains() -> None:
    pid = DepthPidConfig(kp=40, ki=0, kd=0, kp_scale=0.025)
    rig = make_rig(ControllerConfig(depth_pid=pid, watchdog_s=0.0))
    rig.send(b"#start!#mvd.100!")
    rig.set_depth_cm(80)
    rig.tick()
    assert rig.vertical_duties == (-51, -51)


def test_the_output_is_clamped_to_full_thrust(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvpdp.99!#mvd.9999!")
    armed_rig.tick()
    assert armed_rig.vertical_duties == (-255, -255)


def test_gains_zero_means_no_thrust(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvpdp.0!#mvpdi.0!#mvpidd.0!#mvd.500!")
    armed_rig.tick(100)
    assert armed_rig.vertical_duties == (0, 0)


def test_a_new_target_causes_no_derivative_kick(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvpdp.0!#mvpdi.0!#mvpidd.99!#mvd.100!")
    armed_rig.set_depth_cm(100)
    armed_rig.tick(10)
    armed_rig.send(b"#mvd.600!")
    armed_rig.tick()
    assert armed_rig.vertical_duties == (0, 0)


def test_the_derivative_brakes_a_descent(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvpdp.0!#mvpdi.0!#mvpidd.50!#mvd.500!")
    for depth_cm in range(100, 160, 2):  # descending at 2 m/s
        armed_rig.set_depth_cm(depth_cm)
        armed_rig.tick()
    assert armed_rig.vertical_duties[0] > 0  # thrust up against the motion


def test_anti_windup_lets_the_output_recover_at_once(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvpdp.10!#mvpdi.99!#mvpidd.0!#mvd.1000!")
    armed_rig.run(120.0)  # stuck at the surface: saturated down for two minutes
    assert armed_rig.vertical_duties == (-255, -255)
    assert armed_rig.controller.pid.integral_percent >= -100
    armed_rig.set_depth_cm(1100)  # now too deep: the output must reverse within a second
    armed_rig.run(1.0)
    assert armed_rig.vertical_duties[0] > 0


def test_mvpdd_is_accepted_for_mvpidd(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvpdd.12!")
    assert armed_rig.controller.state().gains[2] == 12


def test_gains_come_from_the_configuration() -> None:
    rig = make_rig(ControllerConfig(depth_pid=DepthPidConfig(kp=1, ki=2, kd=3)))
    assert rig.controller.state().gains == (1, 2, 3)


@pytest.mark.parametrize(("depth_cm", "target_cm"), [(30, 0), (0, 30), (100, 0), (0, 1000)])
def test_the_output_is_clamped_to_full_thrust_both_ways(
    armed_rig: Rig, depth_cm: int, target_cm: int
) -> None:
    # P10: clamped to ±100 %, so no duty exceeds mgmp (P8). With kp 99 (4.95 % per cm) an error
    # of 30 cm asks for 148.5 %.
    armed_rig.send(b"#mgmp.200!#mvpdp.99!#mvpdi.0!#mvpidd.0!")
    armed_rig.set_depth_cm(depth_cm)
    armed_rig.send(b"#mvd.%d!" % target_cm)
    armed_rig.tick()
    full = 200 if depth_cm > target_cm else -200
    assert armed_rig.vertical_duties == (full, full)
