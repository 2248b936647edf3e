"""Checks of the checksum mode (P2, P3): switched per frame in both directions, bad frames dropped.

Every check starts in checksum mode off (the runner restores it between checks) and leaves the
wire's decoding mode in step with the controller's.
"""

from __future__ import annotations

from rovlink.conformance.registry import CheckContext, CheckFailedError, check
from rovlink.conformance.replies import check_canonical
from rovlink.conformance.wire import Exchange
from rovlink.protocol import Command, Frame, Setting, lookup, setting_command

__all__: list[str] = []

_QD = Command("qd")
_CRCON = setting_command(Setting.CHECKSUM, True)
_CRCOFF = setting_command(Setting.CHECKSUM, False)


def _checksum_on(ctx: CheckContext) -> None:
    ctx.expect_no_frames(ctx.frame(_CRCON), "#crcon! is answered by nothing")
    ctx.wire.replies_checksummed = True


def _checksum_off(ctx: CheckContext) -> None:
    ctx.expect_no_frames(ctx.frame(_CRCOFF), "#crcoff! is answered by nothing")
    ctx.wire.replies_checksummed = False


@check(
    "checksum-replies",
    ("P2", "P3", "P12"),
    "in checksum mode every reply, each of qsa's six too, carries a correct uppercase checksum",
)
def _replies(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    check_canonical(ctx, ctx.expect_reply(ctx.frame(_QD, checksum=True), ("qd",)))
    qsa = Command("qsa")
    check_canonical(ctx, ctx.expect_reply(ctx.frame(qsa, checksum=True), lookup("qsa").replies))


@check("checksum-missing-dropped", ("P3",), "in checksum mode a frame without checksum is dropped")
def _missing(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    ctx.expect_no_frames(ctx.frame(_QD), "#qd! without checksum in checksum mode")
    ctx.expect_reply(ctx.frame(_QD, checksum=True), ("qd",), "with its checksum")


@check("checksum-bad-dropped", ("P2", "P3"), "in checksum mode a wrong checksum is dropped")
def _bad(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    good = ctx.frame(_QD, checksum=True)
    digits = good[-3:-1]
    for wrong in (b"%02X" % (int(digits, 16) ^ 0x01), b"%02X" % (int(digits, 16) ^ 0x80), b"ZZ"):
        data = good[:-3] + wrong + b"!"
        ctx.expect_no_frames(data, f"{data!r} has a wrong checksum")
    ctx.expect_reply(good, ("qd",), "with its right checksum")


@check("checksum-lowercase-accepted", ("P2",), "a checksum in lowercase hex is accepted")
def _lowercase(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    good = ctx.frame(_QD, checksum=True)
    lower = good[:-3] + good[-3:-1].lower() + b"!"
    if lower == good:  # digits only: no letter to lower, try another query
        good = ctx.frame(Command("qr"), checksum=True)
        lower = good[:-3] + good[-3:-1].lower() + b"!"
    name = "qd" if good.startswith(b"#qd") else "qr"
    ctx.expect_reply(lower, (name,), "a lowercase checksum")


@check(
    "checksum-on-per-frame",
    ("P3",),
    "in #qd!#crcon! sent in one write the reply is plain: a mode change never reaches back",
)
def _on_per_frame(ctx: CheckContext) -> None:
    ctx.wire.replies_checksummed = False
    exchange = ctx.ask(ctx.frame(_QD) + ctx.frame(_CRCON))
    _expect_one(exchange, "qd", "a plain $qd")
    check_canonical(ctx, exchange)
    ctx.wire.replies_checksummed = True
    ctx.expect_reply(ctx.frame(_QD, checksum=True), ("qd",), "the next query is checksummed")


@check(
    "checksum-off-per-frame",
    ("P3",),
    "in #qd<CS>!#crcoff! sent in one write the reply carries a checksum",
)
def _off_per_frame(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    exchange = ctx.ask(ctx.frame(_QD, checksum=True) + ctx.frame(_CRCOFF))
    _expect_one(exchange, "qd", "a checksummed $qd")
    check_canonical(ctx, exchange)
    ctx.wire.replies_checksummed = False
    ctx.expect_reply(ctx.frame(_QD), ("qd",), "the next query is plain")


@check(
    "checksum-on-next-frame",
    ("P3",),
    "in #crcon!#qd<CS>! sent in one write the query is taken and answered with a checksum",
)
def _on_next_frame(ctx: CheckContext) -> None:
    ctx.wire.replies_checksummed = True
    exchange = ctx.ask(ctx.frame(_CRCON) + ctx.frame(_QD, checksum=True))
    _expect_one(exchange, "qd", "a checksummed $qd: the mode acts from the next frame")
    check_canonical(ctx, exchange)


@check(
    "checksum-off-next-frame",
    ("P3",),
    "in checksum mode, in #crcoff!#qd! sent in one write the query is taken and answered plain",
)
def _off_next_frame(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    ctx.wire.replies_checksummed = False
    exchange = ctx.ask(ctx.frame(_CRCOFF) + ctx.frame(_QD))
    _expect_one(exchange, "qd", "a plain $qd: the mode acts from the next frame")
    check_canonical(ctx, exchange)


@check(
    "checksum-off-plain",
    ("P3",),
    "with checksum mode off a frame with checksum digits is an unknown command",
)
def _off_plain(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    _checksum_off(ctx)
    ctx.expect_no_frames(ctx.frame(_QD, checksum=True), "#qd8C! is unknown in plain mode")
    ctx.expect_reply(ctx.frame(_QD), ("qd",), "plain again")


@check(
    "checksum-mode-frames-exact",
    ("P3",),
    "#crcon! and #crcoff! are taken by exact match in either mode, never with a checksum",
)
def _mode_frames(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    _checksum_on(ctx)  # again, in checksum mode, still without checksum
    ctx.expect_reply(ctx.frame(_QD, checksum=True), ("qd",), "still in checksum mode")
    # With its checksum a mode frame is no mode frame (P3): dropped, the mode left as it was.
    crcoff = ctx.with_checksum(ctx.frame(_CRCOFF)[1:-1])
    ctx.expect_no_frames(crcoff, f"{crcoff!r} carries a checksum: dropped")
    ctx.expect_reply(
        ctx.frame(_QD, checksum=True), ("qd",), f"{crcoff!r} must not have left checksum mode"
    )
    _checksum_off(ctx)
    ctx.expect_reply(ctx.frame(_QD), ("qd",), "#crcoff! in checksum mode, without checksum")
    crcon = ctx.with_checksum(ctx.frame(_CRCON)[1:-1])
    ctx.expect_no_frames(crcon, f"{crcon!r} carries a checksum: dropped")
    ctx.expect_reply(ctx.frame(_QD), ("qd",), f"{crcon!r} must not have turned checksum mode on")


@check(
    "checksum-bare-stop-accepted",
    ("P3", "P7"),
    "in checksum mode the bare #stop! is taken (no reply) and the link carries on",
)
def _bare_stop(ctx: CheckContext) -> None:
    _checksum_on(ctx)
    ctx.expect_no_frames(ctx.frame(Command("stop")), "#stop! is answered by nothing")
    ctx.expect_no_frames(ctx.frame(Command("stop"), checksum=True), "#stop<CS>! neither")
    ctx.expect_reply(ctx.frame(_QD, checksum=True), ("qd",), "after #stop!")


def _expect_one(exchange: Exchange, name: str, what: str) -> None:
    frames = exchange.frames
    if len(frames) != 1 or not isinstance(frames[0], Frame) or frames[0].message.name != name:
        raw = b"".join(frame.raw for frame in frames)
        raise CheckFailedError(f"expected {what}, got {repr(raw) if raw else 'nothing'}")
