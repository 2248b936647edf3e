"""Whether ``#stop!`` locks the motors, seen without motion: through the link-loss failsafe.

The protocol has no query for the lock (P4), and its words in debug lines are the controller's
own (P5 says only that there is a line). What a host can see on a bench is P17: unlocked, a
controller that gets no valid frame for the watchdog's time stops the motors and prints a line
(P5: every failsafe action); locked, there is nothing to stop. So, with debug on and in
checksum mode (whose bare ``#stop!`` P3 always honours: the same bytes as the plain one):

* after ``#start!`` (zero thrust set explicitly) and then the bare ``#stop!``, silence for
  longer than the watchdog's time must bring no line: a controller that ignored the ``#stop!``
  is still unlocked, and its failsafe speaks up;
* then, unlocked the same way and silent, a line must come after about the watchdog's time:
  the positive control, without which the silence above proves nothing. Two silences in all,
  as the run of the whole suite has a time budget.

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
#: How much longer than --watchdog a locked controller must stay silent after #stop!.
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


def _expect_locked(ctx: CheckContext, silence_s: float) -> None:
    """Unlock, then the bare ``#stop!``; fail if the failsafe speaks up within ``silence_s``."""
    ctx.tell(_unlock_at_zero_thrust(ctx, checksum=True) + ctx.frame(Command("stop")))
    watched, _ = _watch(ctx, silence_s, until_text=False)
    if watched.received or watched.frames:
        raise CheckFailedError(
            f"after #start! and then the bare #stop! in checksum mode, {silence_s:.1f} s "
            f"without a frame brought {watched.received!r}, as the link-loss failsafe of an "
            f"unlocked controller does: the #stop! did not lock the motors (P7; P3: the bare "
            f"#stop! is always honoured)"
        )


@check(
    STOP_LOCKS_CHECK,
    ("P7", "P3", "P5", "P17"),
    "without motion, at zero thrust, in checksum mode: after #start! and the bare #stop!, "
    "silence past the watchdog's time brings no line; unlocked and silent, the link-loss "
    "failsafe prints its line: #stop! locked the motors (skipped, and said in the summary, "
    "when no failsafe line comes)",
)
def _stop_locks(ctx: CheckContext) -> None:
    ctx.debug_on = True
    watchdog_s = ctx.options.watchdog_s
    ctx.tell(
        ctx.frame(setting_command(Setting.DEBUG, True))
        + ctx.frame(setting_command(Setting.CHECKSUM, True))
    )
    ctx.wire.replies_checksummed = True
    silence_s = watchdog_s + _SILENCE_MARGIN_S
    _expect_locked(ctx, silence_s)
    # The positive control: unlocked, the failsafe acts and says so, within the silence above.
    ctx.tell(_unlock_at_zero_thrust(ctx, checksum=True))
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
    ctx.tell(b"")  # (the failsafe's line may still be arriving; the controller is locked now)
    if first_s >= silence_s:
        raise CheckSkippedError(
            f"#stop! not verified without --motion: unlocked and silent, the controller's "
            f"failsafe line came after {first_s:.1f} s, later than the {silence_s:.1f} s "
            f"watched after #stop! (is its link-loss watchdog longer than --watchdog "
            f"{watchdog_s:g}?)"
        )
