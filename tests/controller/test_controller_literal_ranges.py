"""Every argument's range as PROTOCOL.md writes it, at and just past each edge: the controller
on the wire, and the host's encoder and decoder (see ``tests/protocol/spec_ranges.py``)."""

from __future__ import annotations

import pytest

from rovlink.protocol import ArgumentError, Command, Decoder, Frame, Response
from tests.controller.controller_rig import Rig, make_rig
from tests.protocol.spec_ranges import RESPONSE_RANGES, command_body, edge_cases, value_text
from tests.protocol.test_frames import SEED_FRAMES


def _ready_rig(name: str) -> Rig:
    """Unlocked, debug on, in the vertical mode the command needs (P7, P9)."""
    rig = make_rig(watchdog_s=0.0)
    rig.send(b"#start!#debug1!")
    if name == "mvs":
        rig.send(b"#mvdirect.1!")
    rig.controller.read_output()
    return rig


@pytest.mark.parametrize(("name", "values", "accepted"), edge_cases())
def test_the_controller_takes_each_edge_and_drops_one_past_it(
    name: str, values: tuple[int, ...], accepted: bool
) -> None:
    body = command_body(name, values)
    rig = _ready_rig(name)
    before = rig.controller.state()
    output = rig.send(f"#{body}!".encode())
    if accepted:
        assert output.startswith(b"debug: "), output  # every accepted setting gets a line (P5)
        assert b"dropped" not in output, output
    else:
        # Dropped, never clamped (P6): a line says why, and nothing changed.
        assert output.startswith(b"debug: dropped <" + body.encode() + b">"), output
        assert rig.controller.state() == before


@pytest.mark.parametrize(
    ("frame", "field", "expected"),
    [
        (b"#mgmp.255!", "max_pwm", 255),
        (b"#sdz.1024!", "depth_zero_raw", 1024),
        (b"#sdk.10000!", "depth_k", 10000),
        (b"#mvd.9999!", "target_depth_cm", 9999),
        (b"#th.360.100!", "power_percent", 100),
        (b"#th.360.100!", "direction_deg", 0),  # 360 is 0 (P11)
        (b"#mvpdp.99!", "gains", (99, 30, 20)),
    ],
)
def test_the_top_of_each_range_takes_effect(frame: bytes, field: str, expected: object) -> None:
    rig = make_rig(watchdog_s=0.0)  # (the default configuration: no maximum depth)
    rig.send(b"#start!" + frame)
    assert getattr(rig.controller.state(), field) == expected


def test_a_direction_of_360_drives_as_0() -> None:
    duties = []
    for frame in (b"#th.0.100!", b"#th.360.100!"):
        rig = make_rig(watchdog_s=0.0)
        rig.send(b"#start!" + frame)
        rig.tick()
        duties.append(rig.thrusters.duties)
    assert duties[0] == duties[1]
    assert any(duties[0])


@pytest.mark.parametrize("name", RESPONSE_RANGES)
def test_a_host_decodes_each_reply_edge_and_drops_one_past_it(name: str) -> None:
    minimum, maximum, signed = RESPONSE_RANGES[name]
    for value, accepted in (
        (minimum, True),
        (maximum, True),
        (minimum - 1, False),
        (maximum + 1, False),
    ):
        raw = f"${name}.{value_text(value, signed)}!".encode()
        (event,) = Decoder().feed(raw)
        assert isinstance(event, Frame) is accepted, raw
        if isinstance(event, Frame):
            assert event.message == Response(name, (value,))


@pytest.mark.parametrize(("name", "values", "accepted"), edge_cases())
def test_a_host_sends_each_edge_and_refuses_one_past_it(
    name: str, values: tuple[int, ...], accepted: bool
) -> None:
    if accepted:
        assert (
            str(Command(name, values))
            == "#" + command_body(name, values).replace("mvpdd", "mvpidd") + "!"
        )
    else:
        with pytest.raises(ArgumentError, match="mvpidd" if name == "mvpdd" else name):
            Command(name, values)


@pytest.mark.parametrize("frame", [raw for raw, _, _ in SEED_FRAMES if raw.startswith(b"#")])
def test_the_controller_takes_every_command_frame_of_the_original(frame: bytes) -> None:
    name = frame[1:-1].split(b".")[0].decode()
    rig = _ready_rig("mvs" if name in ("mvs", "mvdirect") else name)
    output = rig.send(frame)
    assert b"dropped" not in output, output
    if name not in ("crcon", "crcoff", "debug1", "debug0"):
        assert output, frame  # a reply, or a line about what it set (P4, P5)
