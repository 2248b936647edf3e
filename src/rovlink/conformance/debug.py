"""Checks of the debug output (P5): text lines that no decoder can take for a frame."""

from __future__ import annotations

from rovlink.conformance.registry import CheckContext, CheckFailedError, check
from rovlink.conformance.wire import Exchange
from rovlink.protocol import MAX_FRAME_BYTES, Command, Setting, setting_command

__all__: list[str] = []

_DEBUG_ON = setting_command(Setting.DEBUG, True)
_DEBUG_OFF = setting_command(Setting.DEBUG, False)
#: Frames every controller drops, with frame characters and odd bytes in what it may describe.
_DROPPED = (
    b"#bogus!",
    b"#mgmp.999!",
    b"$qd.1!",
    b"#q\x01d!",
    b"#" + b"x" * MAX_FRAME_BYTES + b"!",
    b"#th.1.2.3!",
)


def _lines(exchange: Exchange) -> int:
    return exchange.received.count(b"\n")


@check(
    "debug-text-clean",
    ("P5",),
    "with debug on, each dropped frame gets a CR LF line and no line contains # $ or !",
)
def _clean(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(_DEBUG_ON))
    exchange = ctx.expect_no_frames(b"".join(_DROPPED), "dropped frames are answered by text only")
    received = exchange.received
    for character in b"#$!":
        if bytes([character]) in received:
            raise CheckFailedError(f"debug text contains {chr(character)!r}: {received!r}")
    if _lines(exchange) < len(_DROPPED):
        raise CheckFailedError(
            f"{len(_DROPPED)} frames were dropped but only {_lines(exchange)} debug lines came "
            "(P5: a line for every dropped frame)"
        )
    if received.count(b"\r\n") != received.count(b"\n") or not received.endswith(b"\r\n"):
        raise CheckFailedError(f"debug lines must end in CR LF: {received!r}")


@check("debug-off-silent", ("P5",), "with debug off, dropped frames produce no bytes at all")
def _silent(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(_DEBUG_ON) + ctx.frame(_DEBUG_OFF))
    exchange = ctx.tell(b"".join(_DROPPED))
    if exchange.received:
        raise CheckFailedError(f"debug is off but the controller wrote {exchange.received!r}")


@check(
    "debug-mode-per-frame",
    ("P3", "P5"),
    "#debug1! acts from the next frame on: a frame dropped just before it gets no line",
)
def _per_frame(ctx: CheckContext) -> None:
    bogus = b"#bogus!"
    before = ctx.tell(bogus + ctx.frame(_DEBUG_ON))
    ctx.tell(ctx.frame(_DEBUG_OFF))
    after = ctx.tell(ctx.frame(_DEBUG_ON) + bogus)
    if _lines(after) <= _lines(before):
        raise CheckFailedError(
            f"{bogus!r} before #debug1! gave {_lines(before)} lines, after it {_lines(after)}: "
            "the frame dropped before debug was on must not be reported"
        )
    ctx.expect_reply(ctx.frame(Command("qd")), ("qd",), "debug on")
