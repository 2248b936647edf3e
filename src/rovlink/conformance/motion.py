"""Motion checks (opt-in): the motors obey only when unlocked, and ``#stop!`` always stops them.

They drive the vertical thrusters down at low power (``SuiteOptions.motion_percent``) in direct
mode and watch the depth; the vehicle must be in water, free to move a little, and positively
buoyant. Before and during every motion the leak latch is read: a leak, or a query that goes
unanswered, sends ``#stop!`` and aborts the run.
"""

from __future__ import annotations

import time

from rovlink.conformance.registry import CheckAbortedError, CheckContext, CheckFailedError, check
from rovlink.conformance.replies import first_value
from rovlink.protocol import Command

__all__ = ["MOTION_WATCH_S"]

#: How long a motion check watches the depth, s.
MOTION_WATCH_S = 3.0
#: Depth change that counts as moving, cm (a couple of pressure counts).
_MOVED_CM = 5
_POLL_S = 0.1
#: How long the vehicle may coast on after #stop!, s.
_COAST_S = 1.5


def _sample(ctx: CheckContext, checksum: bool) -> int:
    """The depth; abort with ``#stop!`` on a leak or a lost reply."""
    exchange = ctx.ask(
        ctx.frame(Command("qd"), checksum=checksum) + ctx.frame(Command("q.l"), checksum=checksum),
        2,
    )
    names = [frame.message.name for frame in exchange.valid_frames]
    if names != ["qd", "q.l"]:
        _abort(ctx, f"the controller stopped answering queries (got {exchange.received!r})")
    if first_value(exchange, "q.l"):
        _abort(ctx, "the leak sensor fired")
    return first_value(exchange, "qd")


def _abort(ctx: CheckContext, why: str) -> None:
    ctx.wire.link.write(b"#stop!")
    raise CheckAbortedError(f"{why}: #stop! sent, run aborted")


def _watch(ctx: CheckContext, checksum: bool, seconds: float = MOTION_WATCH_S) -> tuple[int, int]:
    """The depth now and the deepest seen over ``seconds``."""
    start = _sample(ctx, checksum)
    deepest = start
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        time.sleep(_POLL_S)
        deepest = max(deepest, _sample(ctx, checksum))
    return start, deepest


def _down(ctx: CheckContext, checksum: bool) -> bytes:
    frame = ctx.frame
    return frame(Command("mvdirect", (1,)), checksum=checksum) + frame(
        Command("mvs", (-ctx.options.motion_percent,)), checksum=checksum
    )


@check(
    "motion-locked-after-stop",
    ("P7",),
    "after #stop!, direct-mode down thrust is dropped: the depth does not grow",
    motion=True,
)
def _locked(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(Command("stop")) + _down(ctx, checksum=False))
    start, deepest = _watch(ctx, checksum=False)
    ctx.tell(ctx.frame(Command("stop")))
    if deepest - start >= _MOVED_CM:
        raise CheckFailedError(f"locked, yet the depth went from {start} to {deepest} cm")


def _dive_then_stop(ctx: CheckContext, checksum: bool) -> None:
    frame = ctx.frame
    ctx.tell(frame(Command("start"), checksum=checksum) + _down(ctx, checksum))
    start, deepest = _watch(ctx, checksum)
    if deepest - start < _MOVED_CM:
        ctx.tell(b"#stop!")
        raise CheckFailedError(
            f"unlocked with {ctx.options.motion_percent} % down thrust, the depth went only "
            f"from {start} to {deepest} cm in {MOTION_WATCH_S:g} s (is the vehicle in water?)"
        )
    ctx.tell(b"#stop!")  # bare, in either mode (P3)
    ctx.tell(_down(ctx, checksum))  # dropped while locked
    _watch(ctx, checksum, _COAST_S)  # the vehicle coasts on a little after its thrust stops
    stopped, deepest_after = _watch(ctx, checksum)
    if deepest_after - stopped >= _MOVED_CM:
        raise CheckFailedError(
            f"after #stop! the depth went on from {stopped} to {deepest_after} cm: "
            "the motors were not stopped and locked"
        )


@check(
    "motion-stop-halts",
    ("P7",),
    "unlocked, down thrust dives; #stop! stops the motors and locks them",
    motion=True,
)
def _stop_halts(ctx: CheckContext) -> None:
    _dive_then_stop(ctx, checksum=False)


@check(
    "motion-bare-stop-in-checksum-mode",
    ("P3", "P7"),
    "in checksum mode, a bare #stop! stops a checksummed dive",
    motion=True,
)
def _bare_stop(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(Command("crcon")))
    ctx.wire.replies_checksummed = True
    _dive_then_stop(ctx, checksum=True)
