"""Every driver method with sample arguments and the exact frames it must send."""

from __future__ import annotations

from typing import Any

from rovlink.client import Sensors
from rovlink.protocol import get_algorithm

#: (method, arguments, frames sent with checksums off)
SET_CASES: list[tuple[str, tuple[Any, ...], dict[str, Any], list[bytes]]] = [
    ("stop", (), {}, [b"#stop!"]),
    ("start", (), {}, [b"#start!"]),
    ("set_debug", (True,), {}, [b"#debug1!"]),
    ("set_debug", (False,), {}, [b"#debug0!"]),
    ("set_max_pwm", (255,), {}, [b"#mgmp.255!"]),
    (
        "set_depth_pid",
        (),
        {"p": 30, "i": 0, "d": 99},
        [b"#mvpdp.30!", b"#mvpdi.0!", b"#mvpidd.99!"],
    ),
    ("set_depth_pid", (), {"i": 4}, [b"#mvpdi.4!"]),
    ("set_direct_mode", (True,), {}, [b"#mvdirect.1!"]),
    ("set_direct_mode", (False,), {}, [b"#mvdirect.0!"]),
    ("set_vertical_thrust", (100,), {}, [b"#mvs.+100!"]),
    ("set_vertical_thrust", (-50,), {}, [b"#mvs.-50!"]),
    ("set_vertical_thrust", (0,), {}, [b"#mvs.+0!"]),
    ("hold_depth", (576,), {}, [b"#mvd.576!"]),
    ("move", (270, 25), {}, [b"#th.270.25!"]),
    ("move", (360, 100), {}, [b"#th.360.100!"]),
    ("set_depth_zero", (1024,), {}, [b"#sdz.1024!"]),
    ("set_depth_scale", (10000,), {}, [b"#sdk.10000!"]),
    ("reset_leak", (), {}, [b"#slreset!"]),
    ("claw_open", (), {}, [b"#h+!"]),
    ("claw_close", (), {}, [b"#h-!"]),
]

#: (method, frame, expected result with the fake's default values)
QUERY_CASES: list[tuple[str, bytes, Any]] = [
    ("depth_cm", b"#qd!", 123),
    ("pressure_raw", b"#qr!", 530),
    ("leak_detected", b"#q.l!", False),
    ("roll_deg", b"#qro!", -1),
    ("pitch_deg", b"#qpi!", 15),
    ("heading_deg", b"#qhe!", 275),
    ("sensors", b"#qsa!", Sensors(123, 530, False, -1, 15, 275)),
]

#: PROTOCOL.md Part 3: bodies with their CRC-8/SMBUS.
CHECKSUM_CASES: list[tuple[str, tuple[Any, ...], bytes]] = [
    ("depth_cm", (), b"#qd8C!"),
    ("hold_depth", (100,), b"#mvd.1004B!"),
    ("move", (270, 25), b"#th.270.25CA!"),
    ("stop", (), b"#stop!"),  # always bare: honoured in either mode (P3)
]


def checksummed(frame: bytes) -> bytes:
    """``frame`` as a client sends it in CRC-8 checksum mode: ``#stop!`` stays bare (P3)."""
    if frame == b"#stop!":
        return frame
    return frame[:-1] + get_algorithm("crc8").digits(frame[1:-1]) + b"!"
