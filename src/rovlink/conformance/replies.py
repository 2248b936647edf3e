"""Checks of the replies: one per query of the command table, the ``qsa`` order and reply time.

Each query gets exactly its replies (P4, P12), valid and in range (P1, P6, P15), written the way
the protocol writes numbers: no leading zeros, a sign on signed values, zero as ``+0`` (P6).
"""

from __future__ import annotations

import math

from rovlink.conformance.registry import CheckContext, CheckFailedError, check
from rovlink.conformance.wire import BITS_PER_BYTE, Exchange
from rovlink.protocol import COMMANDS, Command, Kind, Response, Spec, encode, lookup

__all__ = ["QUERIES", "check_canonical", "expect_depth", "first_value"]

#: Every query of the command table.
QUERIES: tuple[Spec, ...] = tuple(spec for spec in COMMANDS if spec.is_query)

#: P15: a heading is written below the table's maximum, which (360 ≡ 0) is only accepted.
_HEADING_WRITTEN_MAX = lookup("qhe", Kind.RESPONSE).arguments[0].maximum - 1


def check_canonical(ctx: CheckContext, exchange: Exchange) -> None:
    """Fail unless every reply frame is written exactly as the protocol writes it (P2, P6)."""
    algorithm = ctx.options.algorithm if ctx.wire.replies_checksummed else None
    for frame in exchange.valid_frames:
        expected = encode(frame.message, algorithm)
        if frame.raw != expected:
            raise CheckFailedError(
                f"{frame.raw!r} is not written as the protocol writes it: expected {expected!r} "
                "(no leading zeros, a sign on signed values, zero as +0, uppercase checksum)"
            )
        if frame.message.name == "qhe" and frame.message.values[0] > _HEADING_WRITTEN_MAX:
            raise CheckFailedError(
                f"{frame.raw!r}: a heading is written 0–{_HEADING_WRITTEN_MAX} (P15)"
            )


def _expect_nothing_more(ctx: CheckContext, query: str) -> None:
    """Fail if another frame comes within the suite's silence after the replies to ``query``:
    each query is answered exactly once (P4). A second reply a little later (a firmware that
    answers from two places) would pass the query's check and land in a later check's wait,
    which would blame its own rule. (The silence that shows a command unanswered everywhere
    else, not a reply timeout: eight query checks, and the suite's run has a time budget.)"""
    timeout_s = ctx.options.silence_s
    exchange = ctx.wire.send(b"", timeout_s=timeout_s, linger_s=timeout_s)
    ctx.exchanges.append(exchange)
    if exchange.frames:
        raw = b"".join(frame.raw for frame in exchange.frames)
        raise CheckFailedError(
            f"{query} was answered, and then within {timeout_s * 1000:.0f} ms more came: "
            f"{raw!r} (P4: each query is answered exactly once)"
        )


def _query_check(spec: Spec) -> None:
    def run(ctx: CheckContext) -> None:
        exchange = ctx.expect_reply(ctx.frame(Command(spec.name)), spec.replies)
        check_canonical(ctx, exchange)
        _expect_nothing_more(ctx, f"#{spec.name}!")

    names = " ".join(f"${name}" for name in spec.replies)
    check(
        f"query-{spec.name}",
        ("P4", *spec.rules, "P6"),
        f"#{spec.name}! is answered by exactly {names}, in range and canonically written",
    )(run)


for _spec in QUERIES:
    _query_check(_spec)


@check(
    "query-back-to-back",
    ("P1", "P4", "P20"),
    "every query of a burst sent in one write is answered, in order",
)
def _burst(ctx: CheckContext) -> None:
    data = b"".join(ctx.frame(Command(spec.name)) for spec in QUERIES)
    names = tuple(name for spec in QUERIES for name in spec.replies)
    check_canonical(ctx, ctx.expect_reply(data, names))
    _expect_nothing_more(ctx, "every query of the burst")


@check("reply-time", ("P19",), "queries are answered within 5 ms (90th percentile)")
def _reply_time(ctx: CheckContext) -> None:
    frame = ctx.frame(Command("qd"))
    times_s: list[float] = []
    slowest: Exchange | None = None
    for _ in range(ctx.options.timed_queries):
        exchange = ctx.wire.send(frame, frames=1, timeout_s=ctx.options.reply_timeout_s, linger_s=0)
        if exchange.reply_s is None:
            ctx.exchanges.append(exchange)
            raise CheckFailedError("a #qd! got no reply")
        times_s.append(exchange.reply_s)
        if slowest is None or exchange.reply_s > (slowest.reply_s or 0.0):
            slowest = exchange
    if slowest is not None:
        ctx.exchanges.append(slowest)  # the evidence: the slowest exchange
    times_s.sort()
    p90_s = times_s[math.ceil(0.9 * len(times_s)) - 1]
    limit_s = ctx.options.reply_limit_s
    line = ""
    if ctx.options.baudrate and slowest is not None:
        wire_s = (len(slowest.sent) + len(slowest.received)) * BITS_PER_BYTE / ctx.options.baudrate
        limit_s += wire_s
        line = f" + {wire_s * 1000:.2f} ms of bytes on the line at {ctx.options.baudrate} baud"
    if p90_s > limit_s:
        raise CheckFailedError(
            f"90th percentile reply time {p90_s * 1000:.2f} ms > "
            f"{ctx.options.reply_limit_s * 1000:.0f} ms{line} "
            f"(median {times_s[len(times_s) // 2] * 1000:.2f} ms, max {times_s[-1] * 1000:.2f} ms "
            f"over {len(times_s)} queries, from the end of the write to the last byte read)"
        )


def first_value(exchange: Exchange, name: str) -> int:
    """The value of the first valid ``$name`` reply in ``exchange`` (a ``#name!`` that came
    back, as from a controller that echoes, is no reply)."""
    for frame in exchange.valid_frames:
        if isinstance(frame.message, Response) and frame.message.name == name:
            return frame.message.values[0]
    raise CheckFailedError(f"no ${name} reply")


def _expected_depth_cm(raw: int, zero: int, k: int) -> int:
    """P13: clamp(floor((raw − zero) · k / 100), 0, maximum of qd)."""
    maximum = lookup("qd", Kind.RESPONSE).arguments[0].maximum
    return min(max(((raw - zero) * k) // 100, 0), maximum)


def expect_depth(ctx: CheckContext, zero: int, k: int, why: str) -> None:
    """Fail unless the depth in ``$qsa`` follows P13 exactly from the raw reading of the same
    reply, for ``zero`` and ``k``."""
    exchange = ctx.expect_reply(ctx.frame(Command("qsa")), lookup("qsa").replies)
    depth, raw = first_value(exchange, "qd"), first_value(exchange, "qr")
    expected = _expected_depth_cm(raw, zero, k)
    if depth != expected:
        raise CheckFailedError(
            f"{why}: with sdz {zero}, sdk {k} and raw {raw} in the same $qsa, qd should be "
            f"floor(({raw} − {zero}) · {k} / 100) = {expected} (P13), got {depth}"
        )
