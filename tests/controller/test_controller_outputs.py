"""P8 (max PWM) and P11 (the horizontal mixer) through frames."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.controller import DEFAULT_THRUSTERS, ControllerConfig, ThrusterSpec
from tests.controller.controller_rig import Rig, make_rig


def _net_force_and_torque(duties: tuple[int, ...]) -> tuple[float, float, float]:
    """Net surge, sway and yaw of the default layout, taking duty as thrust."""
    surge = sway = torque = 0.0
    for duty, spec in zip(duties, DEFAULT_THRUSTERS[:4], strict=True):
        if spec.vertical:
            continue
        angle = math.radians(spec.angle_deg)
        surge += duty * math.cos(angle)
        sway += duty * math.sin(angle)
        torque += duty * (spec.x_m * math.sin(angle) - spec.y_m * math.cos(angle))
    return surge, sway, torque


def test_full_ahead_runs_every_vectored_thruster_at_max_pwm(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.0.100!")
    armed_rig.tick()
    assert armed_rig.horizontal_duties == (255, 255, 255, 255)
    assert armed_rig.vertical_duties == (0, 0)


def test_half_astern(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.180.50!")
    armed_rig.tick()
    assert armed_rig.horizontal_duties == (-128, -128, -128, -128)


@pytest.mark.parametrize(
    ("frame", "duties"),
    [
        (b"#th.90.100!", (255, -255, -255, 255)),  # starboard
        (b"#th.270.25!", (-64, 64, 64, -64)),  # port at a quarter
        (b"#th.360.100!", (255, 255, 255, 255)),  # 360 is 0
        (b"#th.45.100!", (255, 0, 0, 255)),
        (b"#th.0.0!", (0, 0, 0, 0)),
    ],
)
def test_directions(armed_rig: Rig, frame: bytes, duties: tuple[int, ...]) -> None:
    armed_rig.send(frame)
    armed_rig.tick()
    assert armed_rig.horizontal_duties == duties


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 360), st.integers(1, 100), st.integers(1, 255))
def test_motion_goes_where_asked_without_turning_or_exceeding_max_pwm(
    direction_deg: int, power_percent: int, max_pwm: int
) -> None:
    rig = make_rig(watchdog_s=0.0)
    rig.send(b"#start!#mgmp.%d!#th.%d.%d!" % (max_pwm, direction_deg, power_percent))
    rig.tick()
    duties = rig.horizontal_duties
    # Normalised: the strongest thruster gets exactly power × max PWM (P8, P11).
    assert max(abs(duty) for duty in duties) == int(power_percent / 100 * max_pwm + 0.5 + 1e-9)
    surge, sway, torque = _net_force_and_torque(duties)
    if max(abs(duty) for duty in duties) >= 40:  # below, rounding dominates the direction
        wanted = math.radians(direction_deg)
        got = math.atan2(sway, surge)
        assert abs(math.remainder(got - wanted, 2 * math.pi)) < math.radians(3)
        assert abs(torque) <= 0.35 * 2  # rounding of at most ½ duty per thruster
    assert rig.vertical_duties == (0, 0)


def test_the_set_point_persists_until_changed(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.90.100!")
    armed_rig.tick(500)
    assert armed_rig.horizontal_duties == (255, -255, -255, 255)
    armed_rig.send(b"#mvdirect.1!#mvs.+50!")
    armed_rig.tick()
    assert armed_rig.horizontal_duties == (255, -255, -255, 255)
    armed_rig.send(b"#th.0.0!")
    armed_rig.tick()
    assert armed_rig.horizontal_duties == (0, 0, 0, 0)


def test_max_pwm_scales_every_output(armed_rig: Rig) -> None:
    armed_rig.send(b"#mgmp.100!#th.0.100!#mvdirect.1!#mvs.-50!")
    armed_rig.tick()
    assert armed_rig.thrusters.duties == (100, 100, 100, 100, -50, -50)


def test_max_pwm_zero_keeps_every_thruster_still(armed_rig: Rig) -> None:
    armed_rig.send(b"#mgmp.0!#th.0.100!#mvdirect.1!#mvs.+100!")
    armed_rig.tick()
    assert set(armed_rig.thrusters.duties) == {0}


def test_max_pwm_applies_to_a_running_set_point(armed_rig: Rig) -> None:
    armed_rig.send(b"#th.0.100!")
    armed_rig.tick()
    armed_rig.send(b"#mgmp.200!")
    armed_rig.tick()
    assert armed_rig.horizontal_duties == (200, 200, 200, 200)


def test_the_default_max_pwm_comes_from_the_configuration() -> None:
    rig = make_rig(max_pwm=180, watchdog_s=0.0)
    rig.send(b"#start!#th.0.100!")
    rig.tick()
    assert rig.horizontal_duties == (180, 180, 180, 180)


def test_a_configured_layout_is_mixed_by_its_own_geometry() -> None:
    # Two fixed thrusters pushing ahead, one vertical: no sideways authority at all.
    layout = (
        ThrusterSpec("left", angle_deg=0.0, y_m=-0.2),
        ThrusterSpec("right", angle_deg=0.0, y_m=0.2),
        ThrusterSpec("vertical", vertical=True),
    )
    rig = make_rig(ControllerConfig(thrusters=layout, watchdog_s=0.0))
    rig.send(b"#start!#th.0.100!")
    rig.tick()
    assert rig.thrusters.duties == (255, 255, 0)
    rig.send(b"#th.180.40!")
    rig.tick()
    assert rig.thrusters.duties == (-102, -102, 0)
    rig.send(b"#th.90.100!")
    rig.tick()
    assert rig.thrusters.duties == (0, 0, 0)
    rig.send(b"#mvdirect.1!#mvs.+100!")
    rig.tick()
    assert tuple(rig.thrusters.duties)[2] == 255  # (a fresh tuple: mypy narrowed the old one)
