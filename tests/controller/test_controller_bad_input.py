"""Bad input never stops the controller and never changes its state."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.controller import ControllerState
from rovlink.protocol import COMMANDS, Spec
from tests.controller.controller_rig import Rig, make_rig


def _armed_state_rig() -> Rig:
    """A rig with non-default state everywhere, so that any change would show."""
    rig = make_rig(watchdog_s=0.0)
    rig.send(b"#start!#mgmp.200!#mvpdp.11!#mvpdi.12!#mvpidd.13!#sdz.30!#sdk.250!#th.90.40!")
    rig.send(b"#mvdirect.1!#mvs.-30!#debug1!")
    rig.tick()
    rig.controller.read_output()
    return rig


def _still_works(rig: Rig, before: ControllerState) -> None:
    assert rig.controller.state() == before
    output = rig.send(b"\r\n#qd!")  # ends any unfinished frame or text, then a query
    assert output.endswith(b"$qd.0!")


def _out_of_range_frames(spec: Spec) -> list[bytes]:
    frames = []
    for index, argument in enumerate(spec.arguments):
        for bad in (argument.minimum - 1, argument.maximum + 1):
            values = [str(arg.minimum) for arg in spec.arguments]
            values[index] = f"{bad:+d}" if argument.signed else str(bad)
            frames.append(f"#{spec.name}.{'.'.join(values)}!".encode())
    return frames


OUT_OF_RANGE = [frame for spec in COMMANDS for frame in _out_of_range_frames(spec)]


@pytest.mark.parametrize("frame", OUT_OF_RANGE, ids=lambda frame: frame.decode())
def test_out_of_range_values_change_nothing(frame: bytes) -> None:
    rig = _armed_state_rig()
    before = rig.controller.state()
    assert b"dropped" in rig.send(frame)
    _still_works(rig, before)


@pytest.mark.parametrize(
    "data",
    [
        b"#" + b"m" * 200 + b"!",  # oversize
        b"#mvd.100" + b"0" * 70 + b"!",  # oversize with a valid start
        b"#zz!#stopp!#st op!#sto\x00p!#STOP!",  # unknown, near misses
        b"\xff\xfe\x00\x80#\x81!",  # not ASCII
        b"!!!!$$$$####",
        b"#qd",  # unfinished
        bytes(range(256)),
        b"#mvs.+-5!#th.1.2.3!#mgmp.!#mgmp..1!#.!#!",
    ],
)
def test_garbage_changes_nothing(data: bytes) -> None:
    rig = _armed_state_rig()
    before = rig.controller.state()
    rig.send(data)
    rig.tick(3)
    _still_works(rig, before)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300).map(lambda data: data.replace(b"!", b"")))
def test_random_bytes_without_a_frame_end_change_nothing(data: bytes) -> None:
    rig = _armed_state_rig()
    before = rig.controller.state()
    rig.send(data)
    _still_works(rig, before)


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.sampled_from([b"#", b"$", b"!", b"q", b"d", b".", b"1", b"-", b"\r", b"x"]), max_size=40
    ).map(b"".join)
)
def test_random_frame_like_noise_never_raises(data: bytes) -> None:
    rig = make_rig()
    rig.send(data)
    rig.tick()
    assert rig.send(b"\r\n#qd!").endswith(b"$qd.0!")


def test_noise_between_frames_does_not_disturb_them(armed_rig: Rig) -> None:
    armed_rig.send(b"\x00garbage\r\n#th.90.10!line noise \xff#mvd.300!  \r\n")
    state = armed_rig.controller.state()
    assert (state.direction_deg, state.target_depth_cm) == (90, 300)


def test_a_frame_split_across_reads_is_executed_once_complete(armed_rig: Rig) -> None:
    for byte in b"#mvd.250!":
        armed_rig.send(bytes([byte]))
    assert armed_rig.controller.state().target_depth_cm == 250
