"""Checks of the debug output (P5): text lines that no decoder can take for a frame."""

from __future__ import annotations

from rovlink.conformance.registry import CheckContext, CheckFailedError, check
from rovlink.conformance.wire import Exchange
from rovlink.protocol import MAX_FRAME_BYTES, Command, Setting, encode, lookup, setting_command

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
    ctx.debug_on = True
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


#: Settings with a value, each set to one value and then to another (its minimum, the cautious
#: end, as the set- checks leave it): the second is a change whatever the first found.
_VALUE_SETTINGS = ("mgmp", "mvpdp", "mvpdi", "mvpidd", "sdz", "sdk")


def _first_values() -> bytes:
    """Each value setting at its minimum + 1, so that setting the minimum next is a change."""
    return b"".join(
        encode(Command(name, (lookup(name).arguments[0].minimum + 1,))) for name in _VALUE_SETTINGS
    )


def _setting_changes() -> list[Command]:
    """Frames sent in turn after :func:`_first_values`, each a change that must get a line.
    None moves anything: the mode switches happen locked, and th is sent at 0 % power."""
    return [
        *(Command(name, (lookup(name).arguments[0].minimum,)) for name in _VALUE_SETTINGS),
        setting_command(Setting.DIRECT_MODE, True),
        setting_command(Setting.DIRECT_MODE, False),
        setting_command(Setting.LOCKED, False),
        Command("th", (90, 0)),
        setting_command(Setting.LOCKED, True),
    ]


@check(
    "debug-setting-lines",
    ("P5",),
    "with debug on, each change of a setting or mode gets a debug line: mgmp, the PID gains, "
    "sdz, sdk, mvdirect, start, th (at 0 % power) and stop",
)
def _setting_lines(ctx: CheckContext) -> None:
    ctx.debug_on = True
    ctx.tell(ctx.frame(_DEBUG_ON) + _first_values())
    for change in _setting_changes():
        exchange = ctx.expect_no_frames(ctx.frame(change), f"{change} sets something")
        if _lines(exchange) < 1:
            raise CheckFailedError(
                f"{change} changed a setting with debug on, but no debug line came "
                "(P5: a line for every change of mode or setting)"
            )
