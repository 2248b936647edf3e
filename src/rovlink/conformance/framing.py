"""Checks of the framing (P1, P6): noise, over-long frames, resynchronisation, bad bytes, names.

Each sends something the controller must drop or skip, then a query it must still answer.
"""

from __future__ import annotations

import random

from rovlink.conformance.registry import CheckContext, check
from rovlink.conformance.replies import expect_depth, first_value
from rovlink.protocol import COMMANDS, MAX_FRAME_BYTES, Command, lookup

__all__: list[str] = []

_QD = Command("qd")


def _still_answers(ctx: CheckContext, why: str) -> None:
    ctx.expect_reply(ctx.frame(_QD), ("qd",), why)


@check("noise-between-frames", ("P1",), "CR, LF, spaces and text between frames are skipped")
def _noise_between(ctx: CheckContext) -> None:
    qd = ctx.frame(_QD)
    ctx.expect_reply(b"\r\n  hello 123 \r\n" + qd + b"\r\n" + qd + b" ", ("qd", "qd"))


@check("garbage-survived", ("P1",), "random bytes (seeded) are survived; a query then answers")
def _garbage(ctx: CheckContext) -> None:
    rng = random.Random(ctx.options.seed)
    # Any byte but the start characters, so that no frame can begin by chance; then bytes with
    # start characters that never complete a valid frame ('!' left out).
    noise = bytes(rng.choice([b for b in range(256) if b not in b"#$"]) for _ in range(400))
    starts = bytes(rng.choice(b"#$ab.0\x00\xff") for _ in range(200))
    ctx.expect_no_frames(noise + starts + b"\r\n", "random bytes are no frame")
    _still_answers(ctx, "after random bytes")


@check("overlong-frame-dropped", ("P1",), "a frame over 64 bytes is discarded whole")
def _overlong(ctx: CheckContext) -> None:
    padding = b"0" * MAX_FRAME_BYTES
    ctx.expect_no_frames(b"#qd" + padding + b"!", f"a frame over {MAX_FRAME_BYTES} bytes")
    ctx.expect_no_frames(b"#" + b"q" * (4 * MAX_FRAME_BYTES) + b"!", "a very long frame")
    # A parser without the limit would take this #sdz (its value padded with leading zeros) and
    # move the depth zero above the raw reading: the depth would read 0.
    zero, k = 0, 100
    ctx.settle(ctx.frame(Command("sdz", (zero,))) + ctx.frame(Command("sdk", (k,))))
    raw = first_value(ctx.expect_reply(ctx.frame(Command("qr")), ("qr",)), "qr")
    zero_arg = lookup("sdz").arguments[0]
    value = str(min(raw + 50, zero_arg.maximum)).encode()
    overlong = b"#sdz." + value.rjust(MAX_FRAME_BYTES, b"0") + b"!"
    ctx.expect_no_frames(overlong, "an over-long #sdz")
    expect_depth(ctx, zero, k, "after an over-long #sdz! that must be discarded")
    _still_answers(ctx, "after over-long frames")


@check(
    "longest-frame-accepted",
    ("P1", "P6", "P13"),
    "a frame of exactly 64 bytes (#sdz! with its value padded by leading zeros) is taken: "
    "the depth follows the new zero",
)
def _longest(ctx: CheckContext) -> None:
    zero, k = 0, 100
    ctx.settle(ctx.frame(Command("sdz", (zero,))) + ctx.frame(Command("sdk", (k,))))
    raw = first_value(ctx.expect_reply(ctx.frame(Command("qr")), ("qr",)), "qr")
    # A zero above the raw reading makes the depth read 0, where the zero of 0 read raw.
    padded_zero = min(raw + 50, lookup("sdz").arguments[0].maximum)
    head = b"#sdz."
    frame = head + str(padded_zero).encode().rjust(MAX_FRAME_BYTES - len(head) - 1, b"0") + b"!"
    assert len(frame) == MAX_FRAME_BYTES
    ctx.expect_no_frames(frame, "a #sdz! of 64 bytes is answered by nothing")
    expect_depth(ctx, padded_zero, k, "after a #sdz! of exactly 64 bytes, which must be taken")
    _still_answers(ctx, "after a 64-byte frame")


@check(
    "resync-on-start", ("P1",), "a start character inside an unfinished frame starts a new frame"
)
def _resync(ctx: CheckContext) -> None:
    ctx.expect_reply(b"#qr" + ctx.frame(_QD), ("qd",), "the unfinished #qr is abandoned")
    ctx.expect_reply(b"#qd.12$" + ctx.frame(_QD), ("qd",), "a $ abandons the frame too")


@check("bad-byte-discards", ("P1",), "a byte outside 0x21–0x7E inside a frame discards it")
def _bad_byte(ctx: CheckContext) -> None:
    cases = (b"#q\x01d!", b"#qd\r!", b"#q d!", b"#qd\x80!")
    ctx.expect_no_frames(b"".join(cases), "each frame has a bad byte in its body")
    _still_answers(ctx, "after frames with bad bytes")


@check(
    "unknown-and-malformed-dropped",
    ("P1", "P4", "P6"),
    "unknown names, upper case, missing or extra arguments and non-numbers are dropped",
)
def _unknown(ctx: CheckContext) -> None:
    cases = (
        b"#bogus!",
        b"#QD!",  # commands are case-sensitive
        b"#Qd!",
        b"#qd.1!",  # a query takes no argument
        b"#th.90!",  # th takes two
        b"#th.90.10.5!",
        b"#mgmp.x!",
        b"#mgmp.!",
        b"#mgmp.+10!",  # a sign only where the value is signed
        b"#mvpdp.1e1!",
        b"$qd.12!",  # a reply is no command
        b"#!",
    )
    ctx.expect_no_frames(b"".join(cases), "each of these frames must be dropped")
    _still_answers(ctx, "after unknown and malformed frames")


@check(
    "out-of-range-dropped",
    ("P6",),
    "every argument just outside its range (from the command table) is dropped, not answered",
)
def _out_of_range(ctx: CheckContext) -> None:
    frames: list[bytes] = []
    for spec in COMMANDS:
        for index, argument in enumerate(spec.arguments):
            for bad in (argument.minimum - 1, argument.maximum + 1):
                values = [arg.minimum for arg in spec.arguments]
                values[index] = bad
                text = ".".join(
                    arg.format(value) if arg.signed or value >= 0 else str(value)
                    for arg, value in zip(spec.arguments, values, strict=True)
                )
                frames.append(b"#" + f"{spec.name}.{text}".encode() + b"!")
    ctx.expect_no_frames(b"".join(frames), "each frame has a value out of range")
    _still_answers(ctx, "after out-of-range frames")
