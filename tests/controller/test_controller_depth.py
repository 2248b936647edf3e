"""P13: depth from the raw reading with sdz/sdk; the maximum-depth safety limit."""

from __future__ import annotations

import pytest

from rovlink.controller import ControllerConfig, DepthCalibration
from rovlink.protocol import Decoder, Frame
from tests.controller.controller_rig import Rig, make_rig


@pytest.mark.parametrize(
    ("raw", "zero", "k", "depth_cm"),
    [
        (70, 20, 200, 100),  # the defaults: 2 cm per count
        (20, 20, 200, 0),
        (10, 20, 200, 0),  # below the zero: clamped to the surface
        (21, 20, 150, 1),  # 1.5 cm: floor
        (1024, 0, 10000, 9999),  # clamped to the range of qd
        (500, 100, 0, 0),
        (1024, 1024, 10000, 0),
    ],
)
def test_depth_is_floor_of_raw_minus_zero_times_k_over_100(
    rig: Rig, raw: int, zero: int, k: int, depth_cm: int
) -> None:
    rig.pressure.raw = raw
    assert rig.send(b"#sdz.%d!#sdk.%d!#qd!" % (zero, k)) == b"$qd.%d!" % depth_cm


def test_qr_reports_the_raw_reading(rig: Rig) -> None:
    rig.pressure.raw = 517
    assert rig.send(b"#qr!") == b"$qr.517!"


def test_sdz_and_sdk_take_effect_at_once_for_qd_and_the_pid(armed_rig: Rig) -> None:
    armed_rig.pressure.raw = 70
    armed_rig.send(b"#mvd.100!")
    armed_rig.tick()
    assert armed_rig.controller.depth_cm == 100
    armed_rig.send(b"#sdz.70!")
    assert armed_rig.send(b"#qd!") == b"$qd.0!"
    armed_rig.tick()
    assert armed_rig.controller.depth_cm == 0
    assert armed_rig.vertical_duties[0] < 0  # now "too shallow": dives


def test_the_defaults_come_from_the_configuration() -> None:
    rig = make_rig(ControllerConfig(depth=DepthCalibration(zero_raw=100, k=1000)))
    rig.pressure.raw = 110
    assert rig.send(b"#qd!") == b"$qd.100!"
    assert rig.controller.state().depth_zero_raw == 100


def _limited_rig(max_depth_cm: int = 200) -> Rig:
    config = ControllerConfig(depth=DepthCalibration(max_depth_cm=max_depth_cm), watchdog_s=0.0)
    rig = make_rig(config)
    rig.send(b"#debug1!#start!")
    rig.controller.read_output()
    return rig


def test_max_depth_is_off_by_default(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvd.9999!")
    assert armed_rig.controller.state().target_depth_cm == 9999


def test_targets_deeper_than_the_maximum_are_dropped_with_a_line() -> None:
    rig = _limited_rig()
    assert rig.send(b"#mvd.200!") == b"debug: target depth 200 cm\r\n"
    output = rig.send(b"#mvd.201!")
    assert b"deeper than the maximum depth 200 cm" in output
    assert rig.controller.state().target_depth_cm == 200


def test_past_the_maximum_down_thrust_is_refused_up_thrust_is_not() -> None:
    rig = _limited_rig()
    rig.send(b"#mvdirect.1!#mvs.-100!")
    rig.controller.read_output()
    rig.set_depth_cm(200)
    assert rig.tick() == b""
    assert rig.vertical_duties == (-255, -255)  # at the limit: still allowed
    rig.set_depth_cm(202)
    output = rig.tick(10)
    assert rig.vertical_duties == (0, 0)
    assert output.count(b"past the maximum depth 200 cm") == 1  # one line, not one a tick
    rig.send(b"#mvs.+50!")
    rig.tick()
    assert rig.vertical_duties == (128, 128)
    rig.set_depth_cm(190)
    rig.send(b"#mvs.-100!")
    rig.tick()
    assert rig.vertical_duties == (-255, -255)


def test_noise_at_the_maximum_does_not_flip_the_limit() -> None:
    rig = _limited_rig()
    rig.send(b"#mvdirect.1!#mvs.-100!")
    rig.controller.read_output()
    output = b""
    for depth_cm in (202, 198, 202, 196, 204, 198) * 3:  # noise around the 200 cm limit
        rig.set_depth_cm(depth_cm)
        output += rig.tick()
        assert rig.vertical_duties == (0, 0)  # released only once 5 cm above the limit
    assert output.count(b"past the maximum depth 200 cm") == 1
    rig.set_depth_cm(194)
    rig.tick()
    assert rig.vertical_duties == (-255, -255)


def test_past_the_maximum_the_pid_gives_no_down_thrust() -> None:
    rig = _limited_rig()
    rig.send(b"#mvd.200!")
    rig.set_depth_cm(100)
    rig.run(30.0)  # winds the integral down (diving)
    rig.set_depth_cm(202)
    rig.tick()
    assert rig.vertical_duties[0] >= 0
    assert rig.controller.pid.integral_percent >= 0  # anti-windup follows the narrowed range


def test_a_saturated_depth_reading_is_pushed_no_deeper() -> None:
    # Before, #mvd.2500! with the reading stuck at raw 1024 (2008 cm at the defaults) drove
    # down for ever: the PID saw a depth short of its target that never changed.
    rig = make_rig(ControllerConfig(watchdog_s=0.0))
    rig.send(b"#debug1!#start!#mvd.2500!")
    rig.controller.read_output()
    rig.pressure.raw = 1000
    rig.tick()
    assert rig.vertical_duties[0] < 0  # short of the target, readable: dives
    rig.pressure.raw = 1024
    output = rig.tick(10)
    assert rig.vertical_duties == (0, 0)
    assert output.count(b"depth reading saturated at raw 1024") == 1  # once, not a tick
    rig.send(b"#mvd.100!")  # a target above: up thrust is given
    rig.tick()
    assert rig.vertical_duties[0] > 0


def test_the_top_of_a_10_bit_converter_is_saturated_too() -> None:
    # A 10-bit converter (the simulator's, an Arduino's) tops out at 1023, not at qr's 1024:
    # before, the guard waited for 1024, and #mvd.2500! on the simulated robot dived for ever
    # with the depth stuck at 2006 cm.
    rig = make_rig(ControllerConfig(watchdog_s=0.0))
    rig.send(b"#debug1!#start!#mvd.2500!")
    rig.controller.read_output()
    rig.pressure.raw = 1023
    output = rig.tick()
    assert rig.vertical_duties == (0, 0)
    assert b"depth reading saturated at raw 1023" in output
    # Noise at the top does not flip the hold (nor its debug line) ...
    for raw in (1022, 1023, 1021, 1023, 1022):
        rig.pressure.raw = raw
        output += rig.tick()
        assert rig.vertical_duties == (0, 0)
    assert output.count(b"saturated") == 1
    # ... a reading clearly below the top dives again.
    rig.pressure.raw = 1020
    rig.tick()
    assert rig.vertical_duties[0] < 0


def test_a_depth_scale_of_0_gets_no_down_thrust_from_the_depth_hold() -> None:
    # #sdk.0! is in the protocol's range (P13): every depth then reads 0, and before, a depth
    # hold dived at full thrust with no end (a maximum depth could never trip either).
    rig = make_rig(ControllerConfig(depth=DepthCalibration(max_depth_cm=500), watchdog_s=0.0))
    rig.send(b"#debug1!#start!")
    rig.pressure.raw = 170
    output = rig.send(b"#sdk.0!#mvd.300!")
    assert b"depth coefficient k 0: depth reads 0; a depth hold goes no deeper" in output
    assert rig.send(b"#qd!").endswith(b"$qd.0!")
    rig.tick(10)
    assert rig.vertical_duties == (0, 0)
    rig.send(b"#mvdirect.1!#mvs.-50!")  # direct mode is the pilot's
    rig.tick()
    assert rig.vertical_duties[0] < 0


@pytest.mark.parametrize("raw", [1500, 4095, -7])
def test_the_pid_uses_the_depth_qd_reports_for_a_reading_off_the_scale(raw: int) -> None:
    # P13: "qd reports this value and the PID uses it". A sensor reading past the raw scale
    # (a 12-bit converter) is taken at the top of it, in the control loop as in the replies;
    # before, the loop computed 2960 cm from 1500 while qd said 2008.
    rig = make_rig(watchdog_s=0.0)
    rig.pressure.raw = raw
    rig.send(b"#start!#mvdirect.1!#mvdirect.0!")  # depth mode: hold the depth read now (P9)
    rig.tick()
    (reply,) = Decoder().feed(rig.send(b"#qd!"))
    assert isinstance(reply, Frame)
    (qd_cm,) = reply.message.values
    assert rig.controller.depth_cm == qd_cm
    assert rig.controller.state().target_depth_cm == qd_cm
