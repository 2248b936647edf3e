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
from rovlink.protocol import Command, lookup

__all__ = ["MOTION_WATCH_S"]

#: How long a motion check watches the depth, s.
MOTION_WATCH_S = 3.0
#: Rise of the raw pressure reading that counts as moving deeper, counts (beyond sensor noise).
_MOVED_COUNTS = 3
_POLL_S = 0.1
#: How long the vehicle may coast on after #stop!, s.
_COAST_S = 1.5
#: Silence beyond the watchdog's time before the failsafe must have acted, s.
_WATCHDOG_MARGIN_S = 0.5


def _sample(ctx: CheckContext, checksum: bool) -> int:
    """The raw pressure reading; abort with ``#stop!`` on a leak or a lost reply.

    The raw reading, not the depth: the calibration checks leave ``sdz``/``sdk`` at test values,
    and the raw reading grows with depth whatever they are (P13).
    """
    exchange = ctx.ask(
        ctx.frame(Command("qr"), checksum=checksum) + ctx.frame(Command("q.l"), checksum=checksum),
        2,
    )
    names = [frame.message.name for frame in exchange.valid_frames]
    if names != ["qr", "q.l"]:
        _abort(ctx, f"the controller stopped answering queries (got {exchange.received!r})")
    if first_value(exchange, "q.l"):
        _abort(ctx, "the leak sensor fired")
    return first_value(exchange, "qr")


def _abort(ctx: CheckContext, why: str) -> None:
    ctx.wire.link.write(b"#stop!")
    raise CheckAbortedError(f"{why}: #stop! sent, run aborted")


def _watch(ctx: CheckContext, checksum: bool, seconds: float = MOTION_WATCH_S) -> tuple[int, int]:
    """The raw pressure now and the highest seen over ``seconds``."""
    start = _sample(ctx, checksum)
    deepest = start
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        time.sleep(_POLL_S)
        deepest = max(deepest, _sample(ctx, checksum))
    return start, deepest


def _down(ctx: CheckContext, checksum: bool) -> bytes:
    frame = ctx.frame
    # The PWM cap at its top (the set-* checks leave it at 0): the power is the thrust's %.
    full_pwm = lookup("mgmp").arguments[0].maximum
    return (
        frame(Command("mgmp", (full_pwm,)), checksum=checksum)
        + frame(Command("mvdirect", (1,)), checksum=checksum)
        + frame(Command("mvs", (-ctx.options.motion_percent,)), checksum=checksum)
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
    if deepest - start >= _MOVED_COUNTS:
        raise CheckFailedError(f"locked, yet the raw pressure went from {start} to {deepest}")


def _dive_then_stop(ctx: CheckContext, checksum: bool) -> None:
    frame = ctx.frame
    ctx.tell(frame(Command("start"), checksum=checksum) + _down(ctx, checksum))
    start, deepest = _watch(ctx, checksum)
    if deepest - start < _MOVED_COUNTS:
        ctx.tell(b"#stop!")
        raise CheckFailedError(
            f"unlocked with {ctx.options.motion_percent} % down thrust, the pressure went only "
            f"from raw {start} to {deepest} in {MOTION_WATCH_S:g} s (is the vehicle in water?)"
        )
    ctx.tell(b"#stop!")  # bare, in either mode (P3)
    ctx.tell(_down(ctx, checksum))  # dropped while locked
    _watch(ctx, checksum, _COAST_S)  # the vehicle coasts on a little after its thrust stops
    stopped, deepest_after = _watch(ctx, checksum)
    if deepest_after - stopped >= _MOVED_COUNTS:
        raise CheckFailedError(
            f"after #stop! the raw pressure went on from {stopped} to {deepest_after}: "
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


@check(
    "motion-mode-gating",
    ("P9",),
    "in depth mode, direct-mode thrust (mvs) is dropped: the vehicle does not dive",
    motion=True,
)
def _mode_gating(ctx: CheckContext) -> None:
    frame = ctx.frame
    full_pwm = lookup("mgmp").arguments[0].maximum
    ctx.tell(
        frame(Command("mgmp", (full_pwm,)))
        + frame(Command("start"))
        + frame(Command("mvdirect", (0,)))
        + frame(Command("mvs", (-ctx.options.motion_percent,)))
    )
    start, deepest = _watch(ctx, checksum=False)
    ctx.tell(b"#stop!")
    if deepest - start >= _MOVED_COUNTS:
        raise CheckFailedError(
            f"in depth mode #mvs! was obeyed: the raw pressure went from {start} to {deepest}"
        )


@check(
    "motion-link-loss-failsafe",
    ("P17",),
    "unlocked and diving, no valid frame for the watchdog's time stops and locks the motors",
    motion=True,
)
def _watchdog(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(Command("start")) + _down(ctx, checksum=False))
    # Silence on the line: nothing at all, not even a query, for longer than the watchdog.
    silent_until = time.monotonic() + ctx.options.watchdog_s + _WATCHDOG_MARGIN_S
    while time.monotonic() < silent_until:
        ctx.wire.drain(0.05, limit_s=0.1)
    ctx.tell(_down(ctx, checksum=False))  # dropped if the failsafe locked the motors
    _watch(ctx, False, _COAST_S)
    stopped, deepest = _watch(ctx, checksum=False)
    ctx.tell(b"#stop!")
    if deepest - stopped >= _MOVED_COUNTS:
        raise CheckFailedError(
            f"after {ctx.options.watchdog_s:g} s without a frame the vehicle still dived (raw "
            f"{stopped} to {deepest}): the link-loss failsafe did not stop and lock the motors"
        )
