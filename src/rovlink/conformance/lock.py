"""Whether ``#stop!`` locks the motors, seen without motion: through the link-loss failsafe.

The protocol has no query for the lock (P4), and its words in debug lines are the controller's
own (P5 says only that there is a line). What a host can see on a bench is P17: unlocked, a
controller that gets no valid frame for the watchdog's time stops the motors and prints a line
(P5: every failsafe action); locked, there is nothing to stop. So, with debug on:

* unlocked (``#start!``, zero thrust set explicitly) and silent, a line must come after about
  the watchdog's time: the positive control, which also measures when it comes;
* after ``#start!`` and then ``#stop!``, silence for as long (and a margin) must bring no line: a
  controller that ignored the ``#stop!`` is still unlocked, and its failsafe speaks up;
* the same with the bare ``#stop!`` in checksum mode (P3: always honoured).

No thrust is ever set: the controller is unlocked with neutral set-points (P7), and vertical
and horizontal thrust are set to zero on top, as ``debug-setting-lines`` does. When the positive
control sees no line (the watchdog is off, which P17 allows, or longer than ``--watchdog``, or
the controller never unlocks), the check is skipped, and the run's summary says that ``#stop!``
was not verified.
"""

from __future__ import annotations

from rovlink.conformance.registry import (
    CheckContext,
    CheckFailedError,
    CheckSkippedError,
    check,
)
from rovlink.conformance.wire import Exchange
from rovlink.protocol import Command, Setting, setting_command

__all__ = ["STOP_LOCKS_CHECK"]

#: The name of the check, which the summary of a run names when it was skipped.
STOP_LOCKS_CHECK = "stop-locks"
#: How much longer than the watchdog's time the positive control waits for the failsafe's line.
_CONTROL_MARGIN_S = 1.5
#: How much longer than the failsafe took in the positive control (or --watchdog, if longer) a
#: locked controller must stay silent.
_SILENCE_MARGIN_S = 0.3
#: How long each read of the watch waits, s.
_READ_S = 0.05


def _unlock_at_zero_thrust(ctx: CheckContext, *, checksum: bool) -> bytes:
    """``#start!`` and zero thrust set on top of the neutral set-points it brings (P7, P9:
    entering direct mode sets vertical thrust 0; ``#th.0.0!``: horizontal power 0)."""
    return b"".join(
        ctx.frame(command, checksum=checksum)
        for command in (
            setting_command(Setting.LOCKED, False),
            setting_command(Setting.DIRECT_MODE, True),
            Command("th", (0, 0)),
        )
    )


def _watch(ctx: CheckContext, limit_s: float, *, until_text: bool) -> tuple[Exchange, float]:
    """Send nothing and read for ``limit_s`` (until the first text, if ``until_text``): what
    came, as one exchange, and when the first byte came, s after the start (or ``limit_s``)."""
    wire = ctx.wire
    watched = Exchange(sent=b"")
    started = wire.now_s()
    first_s = limit_s
    while (elapsed_s := wire.now_s() - started) < limit_s:
        piece = wire.send(b"", timeout_s=min(_READ_S, limit_s - elapsed_s), linger_s=_READ_S)
        if piece.received and not watched.received:
            first_s = wire.now_s() - started
        watched.received += piece.received
        watched.events.extend(piece.events)
        if until_text and watched.received:
            break
    ctx.exchanges.append(watched)
    return watched, first_s


def _expect_locked(ctx: CheckContext, stop: bytes, silence_s: float, how: str, rule: str) -> None:
    """Unlock, then ``stop``; fail if the failsafe speaks up within ``silence_s`` of silence."""
    checksum = ctx.wire.replies_checksummed
    ctx.tell(_unlock_at_zero_thrust(ctx, checksum=checksum) + stop)
    watched, _ = _watch(ctx, silence_s, until_text=False)
    if watched.received or watched.frames:
        raise CheckFailedError(
            f"after #start! and then {how}, {silence_s:.1f} s without a frame brought "
            f"{watched.received!r}, as the link-loss failsafe of an unlocked controller does "
            f"(unlocked, its line came after the same silence): {how} did not lock the motors "
            f"({rule})"
        )


@check(
    STOP_LOCKS_CHECK,
    ("P7", "P3", "P5", "P17"),
    "without motion, at zero thrust: unlocked and silent, the link-loss failsafe prints its line "
    "after the watchdog's time; after #stop!, plain and bare in checksum mode, the same silence "
    "brings no line: #stop! locked the motors (skipped, and said in the summary, when no "
    "failsafe line comes)",
)
def _stop_locks(ctx: CheckContext) -> None:
    ctx.debug_on = True
    watchdog_s = ctx.options.watchdog_s
    ctx.tell(ctx.frame(setting_command(Setting.DEBUG, True)))
    # The positive control: unlocked, the failsafe acts and says so; when does its line come?
    ctx.tell(_unlock_at_zero_thrust(ctx, checksum=False))
    control_s = watchdog_s + _CONTROL_MARGIN_S
    watched, first_s = _watch(ctx, control_s, until_text=True)
    if not watched.received:
        raise CheckSkippedError(
            f"#stop! not verified without --motion: unlocked at zero thrust and silent for "
            f"{control_s:g} s, the controller printed no failsafe line (P17, P5), so whether "
            f"#stop! locks cannot be seen (is its link-loss watchdog off, or longer than "
            f"--watchdog {watchdog_s:g}? does #start! unlock?)"
        )
    if watched.frames:
        raw = b"".join(frame.raw for frame in watched.frames)
        raise CheckFailedError(f"nothing was sent, but the controller answered {raw!r}")
    # (the failsafe's line may still be arriving, and the controller is locked again now)
    ctx.tell(b"")
    # Never shorter than --watchdog: text that came sooner may be no failsafe's line.
    silence_s = max(first_s, watchdog_s) + _SILENCE_MARGIN_S
    _expect_locked(ctx, ctx.frame(Command("stop")), silence_s, "#stop!", "P7")
    ctx.tell(ctx.frame(setting_command(Setting.CHECKSUM, True)))
    ctx.wire.replies_checksummed = True
    _expect_locked(
        ctx,
        ctx.frame(Command("stop")),
        silence_s,
        "the bare #stop! in checksum mode",
        "P3: it is always honoured; P7",
    )
