"""Motion checks (opt-in): the motors obey only when unlocked, and ``#stop!`` always stops them.

They drive the vertical thrusters down at low power (``SuiteOptions.motion_percent``) in direct
mode and watch the depth; the vehicle must be in water, free to move a little, and positively
buoyant. Before and during every motion the leak latch is read: a leak, or a query that goes
unanswered, sends ``#stop!`` and aborts the run.
"""

from __future__ import annotations

import functools
import itertools
import time
from collections.abc import Callable

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
#: After a failed check, how many coasts the vehicle is watched for to come to rest.
_SETTLE_COASTS = 3
#: The other cause of a vehicle that does not dive when it must, said with "is it in water?":
#: a controller that never unlocks fails every motion check for want of a dive.
_UNLOCKS = "does the controller unlock the motors on #start!"
#: Silence beyond the watchdog's time before the failsafe must have acted, s.
_WATCHDOG_MARGIN_S = 0.5
#: What the failsafe check sends instead of silence: nothing that P1 lets be a frame at all, so
#: that no reading of P17's "valid frame" counts it (a well-formed unknown command or a reply
#: might be read as valid by some controllers; noise, a frame with a control byte, one longer
#: than 64 bytes and an unfinished one cannot).
_NOT_FRAMES = (
    b"\r\n  noise \x00\xff 123 \r\n",
    b"#q\x01d!",
    b"#" + b"q" * 80 + b"!",
    b"#qd",  # unfinished, then abandoned by the next start character
)


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


def _watch(
    ctx: CheckContext, checksum: bool, seconds: float = MOTION_WATCH_S, *, coast: bool = False
) -> tuple[int, int]:
    """The raw pressure now and the highest seen over ``seconds``, or until the vehicle has
    moved deeper (by ``_MOVED_COUNTS``): whether a check wanted a dive or none, a dive seen
    decides it, and only "no dive" needs the whole watch. ``coast``: the whole time, whatever
    is seen (the vehicle settling after its thrust stopped)."""
    start = _sample(ctx, checksum)
    deepest = start
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and (coast or deepest - start < _MOVED_COUNTS):
        time.sleep(_POLL_S)
        deepest = max(deepest, _sample(ctx, checksum))
    return start, deepest


def _come_to_rest(ctx: CheckContext, failure: CheckFailedError) -> None:
    """After ``failure``: stop the motors and watch the vehicle until it no longer goes deeper,
    so that the next check does not take the coast of this one's dive for its own (and blame a
    rule the controller obeys). Abort the run if it goes on diving: more checks would only
    drive it deeper."""
    settling = CheckContext(ctx.wire, ctx.options)  # (its exchanges are not the failure's)
    # #crcoff! first, on its own: a failed check may have left checksum mode on. Nothing
    # else: a depth mode entered now would hold the vehicle whether the #stop! worked or not.
    settling.tell(b"#crcoff!")
    settling.tell(b"#stop!")
    ctx.wire.replies_checksummed = False
    for _ in range(_SETTLE_COASTS):
        start, deepest = _watch(settling, False, _COAST_S, coast=True)
        if deepest - start < _MOVED_COUNTS:
            return
    _abort(
        ctx,
        f"{failure}; and after a plain #stop! the vehicle still went deeper (raw {start} to "
        f"{deepest} in the last {_COAST_S:g} s of {_SETTLE_COASTS * _COAST_S:g})",
    )


def _motion_check(
    name: str, rules: tuple[str, ...], description: str
) -> Callable[[Callable[[CheckContext], None]], Callable[[CheckContext], None]]:
    """Register a motion check that, when it fails, leaves the vehicle at rest for the next."""

    def register(run: Callable[[CheckContext], None]) -> Callable[[CheckContext], None]:
        @functools.wraps(run)
        def ending_at_rest(ctx: CheckContext) -> None:
            try:
                run(ctx)
            except CheckFailedError as failure:
                _come_to_rest(ctx, failure)
                raise

        check(name, rules, description, motion=True)(ending_at_rest)
        return run

    return register


def _down(ctx: CheckContext, checksum: bool) -> bytes:
    frame = ctx.frame
    # The PWM cap at its top (the set-* checks leave it at 0): the power is the thrust's %.
    full_pwm = lookup("mgmp").arguments[0].maximum
    return (
        frame(Command("mgmp", (full_pwm,)), checksum=checksum)
        + frame(Command("mvdirect", (1,)), checksum=checksum)
        + frame(Command("mvs", (-ctx.options.motion_percent,)), checksum=checksum)
    )


@_motion_check(
    "motion-locked-after-stop",
    ("P7",),
    "after #stop!, down thrust in direct mode and a depth target far below in depth mode are "
    "dropped: the depth does not grow, nor after a #start! alone",
)
def _locked(ctx: CheckContext) -> None:
    frame = ctx.frame
    thrust = f"#mvs.-{ctx.options.motion_percent}!"
    target = f"#mvd.{lookup('mvd').arguments[0].maximum}!"
    # Each motion command sent while locked, then a bare #start!: dropped (P7), not kept as a
    # set-point that the #start! brings back.
    for what, data in (
        (thrust, _down(ctx, checksum=False)),
        (
            target,
            _depth_far_below(ctx)
            + frame(Command("mvdirect", (0,)))
            + frame(Command("mvd", (lookup("mvd").arguments[0].maximum,))),
        ),
    ):
        _expect_no_dive(
            ctx, frame(Command("stop")) + data, f"locked, yet {what} was obeyed", stop=False
        )
        _expect_no_dive(
            ctx,
            frame(Command("start")),
            f"{what} sent while locked was kept and obeyed at a #start! alone (P7: motion "
            "commands are dropped while locked, and #start! unlocks with neutral set-points)",
        )
    _expect_dive(
        ctx,
        frame(Command("start")) + _down(ctx, checksum=False),
        "unlocked, the same thrust",
        "thrust obeyed while locked",
    )


def _dive_then_stop(ctx: CheckContext, checksum: bool, *, then_start: bool = False) -> None:
    frame = ctx.frame
    ctx.tell(frame(Command("start"), checksum=checksum) + _down(ctx, checksum))
    start, deepest = _watch(ctx, checksum)
    if deepest - start < _MOVED_COUNTS:
        ctx.tell(b"#stop!")
        raise CheckFailedError(
            f"unlocked with {ctx.options.motion_percent} % down thrust, the pressure went only "
            f"from raw {start} to {deepest} in {MOTION_WATCH_S:g} s (is the vehicle in water? "
            f"{_UNLOCKS}?)"
        )
    ctx.tell(b"#stop!")  # bare, in either mode (P3)
    ctx.tell(_down(ctx, checksum))  # dropped while locked
    _watch(
        ctx, checksum, _COAST_S, coast=True
    )  # the vehicle coasts on a little after its thrust stops
    stopped, deepest_after = _watch(ctx, checksum)
    if deepest_after - stopped >= _MOVED_COUNTS:
        raise CheckFailedError(
            f"after #stop! the raw pressure went on from {stopped} to {deepest_after}: "
            "the motors were not stopped and locked"
        )
    if then_start:
        _start_is_neutral(ctx, checksum)


def _start_is_neutral(ctx: CheckContext, checksum: bool) -> None:
    """A bare ``#start!`` after the stop must not bring the dive back: ``#stop!`` cleared the
    set-points, and ``#start!`` unlocks with neutral ones (P7)."""
    start_frame = ctx.frame(Command("start"), checksum=checksum)
    start, deepest = _watched_then_stopped(ctx, start_frame, checksum=checksum)
    if deepest - start >= _MOVED_COUNTS:
        raise CheckFailedError(
            f"#start! alone after #stop! dived again (raw {start} to {deepest}): #stop! must "
            "clear the motion set-points, the thrust sent after it while locked must be "
            "dropped, and #start! unlock with neutral ones (P7)"
        )


@_motion_check(
    "motion-stop-halts",
    ("P7",),
    "unlocked, down thrust dives; #stop! stops the motors and locks them, and clears the "
    "set-points: a #start! alone after it does not dive again",
)
def _stop_halts(ctx: CheckContext) -> None:
    _dive_then_stop(ctx, checksum=False, then_start=True)


@_motion_check(
    "motion-bare-stop-in-checksum-mode",
    ("P3", "P7"),
    "in checksum mode, a bare #stop! stops a checksummed dive",
)
def _bare_stop(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(Command("crcon")))
    ctx.wire.replies_checksummed = True
    _dive_then_stop(ctx, checksum=True)


def _capped_pwm(ctx: CheckContext) -> int:
    """The PWM cap that makes full thrust ``motion_percent`` (a depth target far below drives
    the PID to its limit; the cap keeps that dive as gentle as the others)."""
    full_pwm = lookup("mgmp").arguments[0].maximum
    return max(round(full_pwm * ctx.options.motion_percent / 100), 1)


def _depth_far_below(ctx: CheckContext) -> bytes:
    """A proportional gain and a calibration under which ``#mvd.<max>!`` is far below the
    vehicle: obeyed, it dives (the set- checks leave the gains at 0, the calibration checks
    the depth anywhere)."""
    frame = ctx.frame
    return (
        frame(Command("sdz", (0,)))
        + frame(Command("sdk", (1,)))  # the depth reads raw / 100: at most about 10 cm
        + frame(Command("mvpdp", (50,)))
        + frame(Command("mgmp", (_capped_pwm(ctx),)))
    )


def _watched_then_stopped(
    ctx: CheckContext, data: bytes, *, checksum: bool = False
) -> tuple[int, int]:
    """Send ``data``, watch the pressure, then ``#stop!`` (whatever the watch raises): the raw
    pressure at the start and the deepest seen."""
    ctx.tell(data)
    try:
        return _watch(ctx, checksum)
    finally:
        ctx.tell(b"#stop!")


def _expect_no_dive(ctx: CheckContext, data: bytes, what: str, *, stop: bool = True) -> None:
    """Send ``data`` and fail if the vehicle dives. ``#stop!`` after the watch, unless ``stop``
    is false and the vehicle did not dive: what comes next then finds the state ``data`` left
    (a #stop! would clear a set-point that a locked controller kept)."""
    if stop:
        start, deepest = _watched_then_stopped(ctx, data)
    else:
        ctx.tell(data)
        try:
            start, deepest = _watch(ctx, False)
        except BaseException:
            ctx.tell(b"#stop!")
            raise
    if deepest - start >= _MOVED_COUNTS:
        if not stop:
            ctx.tell(b"#stop!")
        raise CheckFailedError(f"{what}: the raw pressure went from {start} to {deepest}")


def _expect_dive(ctx: CheckContext, data: bytes, what: str, unseen: str) -> None:
    """The positive control of a check that passes when the vehicle does not dive: ``data``
    (obeyed, as it must be) dives it. Without it a vehicle that cannot dive at all (out of the
    water, too buoyant for the power) would pass the check whatever the controller does."""
    start, deepest = _watched_then_stopped(ctx, data)
    # Stopped, the vehicle coasts on a little: the next check must not see that as its dive.
    _watch(ctx, False, _COAST_S, coast=True)
    if deepest - start < _MOVED_COUNTS:
        raise CheckFailedError(
            f"{what} did not dive the vehicle either (raw {start} to {deepest} in "
            f"{MOTION_WATCH_S:g} s), so {unseen} could not be seen (is the vehicle in water, "
            f"and {ctx.options.motion_percent} % enough to dive it? --motion-power; {_UNLOCKS}?)"
        )


@_motion_check(
    "motion-mode-gating",
    ("P9", "P6"),
    "in depth mode mvs is dropped, in direct mode mvd is dropped: the vehicle does not dive "
    "(nor for mvs.-101 and mvd.10000, out of range: dropped, not clamped)",
)
def _mode_gating(ctx: CheckContext) -> None:
    frame = ctx.frame
    deepest_cm = lookup("mvd").arguments[0].maximum
    # Every dive below is at most motion_percent: full thrust under the capped PWM. Depth mode
    # holds the depth it is entered at; an out-of-range target clamped to the deepest would dive.
    _expect_no_dive(
        ctx,
        _depth_far_below(ctx)
        + frame(Command("start"))
        + frame(Command("mvdirect", (0,)))
        + frame(Command("mvs", (lookup("mvs").arguments[0].minimum,)))  # -100 % of the cap
        + b"#mvd.%d!" % (deepest_cm + 1),
        "in depth mode #mvs! or the out-of-range #mvd! was obeyed",
    )
    # Direct mode with no thrust: a target far below, if taken (P9: dropped), would dive; so
    # would an out-of-range thrust clamped to -100 %.
    _expect_no_dive(
        ctx,
        _depth_far_below(ctx)
        + frame(Command("start"))
        + frame(Command("mvdirect", (1,)))
        + frame(Command("mvd", (deepest_cm,)))
        + b"#mvs.-101!",
        "in direct mode #mvd! or the out-of-range #mvs.-101! was obeyed",
    )
    _expect_dive(
        ctx,
        _depth_far_below(ctx)
        + frame(Command("start"))
        + frame(Command("mvdirect", (1,)))
        + frame(Command("mvs", (lookup("mvs").arguments[0].minimum,))),
        "in direct mode, #mvs.-100! under the same PWM cap",
        "a command of the other mode obeyed",
    )


@_motion_check(
    "motion-out-of-range-not-clamped",
    ("P6", "P8"),
    "with the PWM cap at 0 and down thrust set, an out-of-range #mgmp.256! is dropped, not "
    "clamped to 255: the vehicle does not dive",
)
def _pwm_not_clamped(ctx: CheckContext) -> None:
    frame = ctx.frame
    maximum = lookup("mgmp").arguments[0].maximum
    _expect_no_dive(
        ctx,
        frame(Command("mgmp", (0,)))
        + frame(Command("start"))
        + frame(Command("mvdirect", (1,)))
        + frame(Command("mvs", (-ctx.options.motion_percent,)))
        + b"#mgmp.%d!" % (maximum + 1),
        f"#mgmp.{maximum + 1}! was clamped, not dropped",
    )
    _expect_dive(
        ctx,
        frame(Command("start")) + _down(ctx, checksum=False),
        f"with #mgmp.{maximum}!, the same thrust",
        "a clamped PWM cap",
    )


#: The depth PID's gains (P10): no query reads them back, so only a dive shows one clamped.
_GAINS = ("mvpdp", "mvpdi", "mvpidd")


@_motion_check(
    "motion-gains-out-of-range-not-clamped",
    ("P6", "P10"),
    "in depth mode, every PID gain at 0 and a target far below, #mvpdp.100! #mvpdi.100! "
    "#mvpidd.100! are dropped, not clamped to 99: the vehicle does not dive (#mvpdp.99! then does; "
    "a clamped derivative gain cannot show on a vehicle at rest)",
)
def _gains_not_clamped(ctx: CheckContext) -> None:
    # With every gain at 0 the PID drives nothing, however far the target; a proportional or
    # integral gain clamped to its maximum drives the dive at once. (A derivative gain on
    # measurement, P10, acts only while the depth changes: a vehicle at rest cannot show it.)
    frame = ctx.frame
    top = lookup(_GAINS[0]).arguments[0].maximum
    depth_hold = (
        _depth_far_below(ctx)
        + b"".join(frame(Command(name, (0,))) for name in _GAINS)
        + frame(Command("mvdirect", (0,)))
        + frame(Command("start"))
        + frame(Command("mvd", (lookup("mvd").arguments[0].maximum,)))
    )
    too_high = b"".join(b"#%s.%d!" % (name.encode(), top + 1) for name in _GAINS)
    _expect_no_dive(
        ctx, depth_hold + too_high, f"a PID gain out of range ({too_high.decode()}) was clamped"
    )
    # The same set-up with the gain in range dives: the watch above could have seen it.
    start, deepest = _watched_then_stopped(ctx, depth_hold + frame(Command(_GAINS[0], (top,))))
    if deepest - start < _MOVED_COUNTS:
        raise CheckFailedError(
            f"with #{_GAINS[0]}.{top}! in range the depth hold did not dive either (raw {start} "
            f"to {deepest} in {MOTION_WATCH_S:g} s), so a clamped gain could not be seen (is the "
            f"vehicle in water? {_UNLOCKS}?)"
        )


@_motion_check(
    "motion-link-loss-failsafe",
    ("P17",),
    "unlocked and diving, queries alone keep the link alive past the watchdog's time; no valid "
    "frame for that time (only noise and broken frames: a control byte, over 64 bytes, "
    "unfinished) stops and locks the motors",
)
def _watchdog(ctx: CheckContext) -> None:
    ctx.tell(ctx.frame(Command("start")) + _down(ctx, checksum=False))
    # First the dive, the positive control: a vehicle that does not dive at all would show
    # no dive after the silence either, failsafe or none.
    start, deepest = _watch(ctx, checksum=False)
    if deepest - start < _MOVED_COUNTS:
        ctx.tell(b"#stop!")
        raise CheckFailedError(
            f"unlocked with {ctx.options.motion_percent} % down thrust the vehicle did not dive "
            f"(raw {start} to {deepest} in {MOTION_WATCH_S:g} s), so the failsafe could not be "
            f"seen (is the vehicle in water? --motion-power; {_UNLOCKS}?)"
        )
    # Queries alone, for longer than the watchdog and the coast after it: they are valid
    # frames, so they keep the link alive (P17), and the dive goes on. A failsafe that only
    # motion commands feed stops a host that relays a steady motion and polls its sensors.
    queried_s = ctx.options.watchdog_s + _COAST_S + _WATCHDOG_MARGIN_S
    alive_until = time.monotonic() + queried_s
    while time.monotonic() < alive_until:
        _sample(ctx, checksum=False)
        time.sleep(_POLL_S)
    start, deepest = _watch(ctx, checksum=False)
    if deepest - start < _MOVED_COUNTS:
        ctx.tell(b"#stop!")
        raise CheckFailedError(
            f"with only queries sent for {queried_s:g} s, more than the "
            f"watchdog's {ctx.options.watchdog_s:g} s, the dive stopped (raw {start} to "
            f"{deepest} in {MOTION_WATCH_S:g} s): any valid frame, a query too, must keep the "
            "link alive (P17)"
        )
    # No valid frame for longer than the watchdog, but bytes all the time: noise and frames
    # P1 discards. Only valid frames may feed the failsafe (P17).
    silent_until = time.monotonic() + ctx.options.watchdog_s + _WATCHDOG_MARGIN_S
    junk = iter(itertools.cycle(_NOT_FRAMES))
    while time.monotonic() < silent_until:
        ctx.wire.link.write(next(junk))
        ctx.wire.drain(0.05, limit_s=0.1)
    ctx.tell(_down(ctx, checksum=False))  # dropped if the failsafe locked the motors
    _watch(ctx, False, _COAST_S, coast=True)
    stopped, deepest = _watch(ctx, checksum=False)
    ctx.tell(b"#stop!")
    if deepest - stopped >= _MOVED_COUNTS:
        raise CheckFailedError(
            f"after {ctx.options.watchdog_s:g} s without a frame the vehicle still dived (raw "
            f"{stopped} to {deepest}): the link-loss failsafe did not stop and lock the motors"
        )
