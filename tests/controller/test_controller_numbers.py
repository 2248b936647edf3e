"""P6: decimal numbers, leading zeros, signs only where signed, out of range is dropped."""

from __future__ import annotations

import pytest

from tests.controller.controller_rig import Rig


def test_leading_zeros_are_accepted(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvd.0100!#th.090.050!#mgmp.007!")
    state = armed_rig.controller.state()
    assert (state.target_depth_cm, state.direction_deg, state.power_percent) == (100, 90, 50)
    assert state.max_pwm == 7


@pytest.mark.parametrize(
    "frame",
    [
        b"#mgmp.256!",
        b"#mgmp.-1!",
        b"#mgmp.+10!",
        b"#mvpdp.100!",
        b"#sdz.1025!",
        b"#sdk.10001!",
        b"#mvd.10000!",
        b"#th.361.10!",
        b"#th.10.101!",
        b"#mvdirect.2!",
    ],
)
def test_out_of_range_or_wrongly_signed_values_are_dropped_never_clamped(
    armed_rig: Rig, frame: bytes
) -> None:
    before = armed_rig.controller.state()
    assert armed_rig.send(frame) == b""
    assert armed_rig.controller.state() == before


@pytest.mark.parametrize(
    "frame",
    [
        b"#mvd.1a!",
        b"#mvd.!",
        b"#mvd!",
        b"#mvd.1.2!",
        b"#th.10!",
        b"#mvd. 1!",
        b"#mvd.0x10!",
        b"#mvd.1e2!",
        b"#mvd.--1!",
        b"#qd.1!",
        b"#start.1!",
    ],
)
def test_malformed_numbers_are_dropped(armed_rig: Rig, frame: bytes) -> None:
    before = armed_rig.controller.state()
    armed_rig.send(frame)
    assert armed_rig.controller.state() == before


def test_mvs_takes_a_sign_or_a_bare_non_negative_value(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvdirect.1!")
    for frame, expected in [
        (b"#mvs.+100!", 100),
        (b"#mvs.-50!", -50),
        (b"#mvs.50!", 50),
        (b"#mvs.+0!", 0),
        (b"#mvs.-0!", 0),
        (b"#mvs.-100!", -100),
    ]:
        armed_rig.send(frame)
        assert armed_rig.controller.state().vertical_thrust_percent == expected, frame


def test_mvs_out_of_range_keeps_the_previous_thrust(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvdirect.1!#mvs.+40!#mvs.+101!#mvs.-101!")
    assert armed_rig.controller.state().vertical_thrust_percent == 40


@pytest.mark.parametrize("frame", [b"#QD!", b"#Start!", b"#MVD.100!", b"#Qd!"])
def test_commands_are_case_sensitive(debug_rig: Rig, frame: bytes) -> None:
    output = debug_rig.send(frame)
    assert b"unknown" in output
    assert b"$" not in output


def test_replies_have_no_leading_zeros_and_signed_values_always_a_sign(rig: Rig) -> None:
    rig.pressure.raw = 25
    assert rig.send(b"#qd!#qr!") == b"$qd.10!$qr.25!"
    assert rig.send(b"#qro!") == b"$qro.+0!"
