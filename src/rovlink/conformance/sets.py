"""Checks of the commands that set something (P4, P7, P13): no reply, and calibration that acts.

With debug off (as every check starts) a setting other than the debug mode is answered by
nothing at all: no frame, and no text either (an ``OK`` line a host would skip still breaks P4 and
P5).

Every command of the table that is not a query gets a check that it is answered by no frame.
The values sent are each argument's minimum: the cautious end (no PWM, no gain, no thrust).
Motion commands are sent while the motors are locked, so they move nothing. The controller keeps
these settings until it is reset; the summary says so.
"""

from __future__ import annotations

from rovlink.conformance.registry import CheckContext, CheckSkippedError, check
from rovlink.conformance.replies import expect_depth, first_value
from rovlink.protocol import COMMANDS, Command, Setting, Spec, lookup, setting_command

__all__ = ["SETTERS"]

#: Commands that set something, apart from the checksum mode frames (their own checks) and
#: ``start`` (checked with ``stop`` right after it, so the motors are never left unlocked).
SETTERS: tuple[Spec, ...] = tuple(
    spec
    for spec in COMMANDS
    if not spec.is_query
    and spec.setting is not Setting.CHECKSUM
    and spec.setting is not Setting.LOCKED
)


def _setter_check(spec: Spec) -> None:
    command = Command(spec.name, tuple(argument.minimum for argument in spec.arguments))
    # #debug1! turns debug on and prints its line (P5); with debug off, every other setting,
    # #debug0! too, is answered by nothing at all.
    turns_debug_on = command == setting_command(Setting.DEBUG, True)

    def run(ctx: CheckContext) -> None:
        # (the motors are locked: every check starts after the runner's #stop!)
        ctx.debug_on = turns_debug_on
        ctx.expect_no_frames(ctx.frame(command), f"{command} sets something: no reply (P4)")
        ctx.expect_reply(ctx.frame(Command("qd")), ("qd",), f"after {command}")

    check(
        f"set-{spec.name}",
        ("P4", *spec.rules),
        f"{spec.template()} is answered by no frame"
        + ("" if turns_debug_on else ", and by no text with debug off"),
    )(run)


#: Replies read per calibration (the raw reading moves with sensor noise between them).
_SAMPLES = 4

for _spec in SETTERS:
    _setter_check(_spec)


@check(
    "start-stop-silent",
    ("P4", "P7"),
    "#start! and #stop! are answered by no frame, and by no text with debug off",
)
def _start_stop(ctx: CheckContext) -> None:
    ctx.expect_no_frames(
        ctx.frame(Command("start")) + ctx.frame(Command("stop")),
        "start and stop set something: no reply (P4)",
    )
    ctx.expect_no_frames(ctx.frame(Command("stop")), "a second #stop! is answered by nothing")
    ctx.expect_reply(ctx.frame(Command("qd")), ("qd",), "after #stop!")


@check(
    "calibration-applies",
    ("P13", "P12"),
    "after #sdz! and #sdk! the depth in $qsa is floor((raw − zero) · k / 100), clamped, exactly "
    "from the raw of the same reply (k 175 tells floor from rounding)",
)
def _calibration(ctx: CheckContext) -> None:
    raw = first_value(ctx.expect_reply(ctx.frame(Command("qr")), ("qr",)), "qr")
    # k 175: (raw − zero) · 1.75 has a fraction of .25, .5 or .75 three times in four, so a
    # controller that rounds is caught over the samples; the 1024 clamps at 0 and 9999.
    cases = ((0, 100), (max(raw - 5, 0), 175), (max(raw - 3, 0), 10000), (min(raw + 50, 1024), 500))
    for zero, k in cases:
        ctx.settle(ctx.frame(Command("sdz", (zero,))) + ctx.frame(Command("sdk", (k,))))
        for _ in range(_SAMPLES):
            expect_depth(ctx, zero, k, "sdz and sdk take effect at once")


@check(
    "calibration-range-ends-taken",
    ("P6", "P13"),
    "#sdz! and #sdk! at each end of their range are taken, not dropped: #sdz.<max>! and "
    "#sdk.0! each bring the depth to 0",
)
def _calibration_ends(ctx: CheckContext) -> None:
    # Each end in turn, from a calibration whose depth is not 0 (the raw reading times 100,
    # clamped): a controller whose range ends one short (a < for a <=) drops the frame, and
    # the depth stays where it was.
    zero_arg, k_arg = lookup("sdz").arguments[0], lookup("sdk").arguments[0]
    if first_value(ctx.expect_reply(ctx.frame(Command("qr")), ("qr",)), "qr") == 0:
        raise CheckSkippedError(
            "the raw pressure reads 0: every calibration gives the depth 0, so whether the "
            "range's ends are taken cannot be seen"
        )
    deep = ctx.frame(Command("sdz", (zero_arg.minimum,))) + ctx.frame(
        Command("sdk", (k_arg.maximum,))
    )
    for name, zero, k in (
        ("sdz", zero_arg.maximum, k_arg.maximum),
        ("sdk", zero_arg.minimum, k_arg.minimum),
    ):
        ctx.settle(deep)
        value = zero if name == "sdz" else k
        argument = zero_arg if name == "sdz" else k_arg
        ctx.settle(ctx.frame(Command(name, (value,))))
        expect_depth(
            ctx,
            zero,
            k,
            f"#{name}.{value}! is in range ({argument.minimum}–{argument.maximum}) and must be "
            "taken",
        )


@check(
    "calibration-out-of-range-not-clamped",
    ("P6", "P13"),
    "#sdz! and #sdk! just out of range are dropped, not clamped: the depth keeps its calibration",
)
def _calibration_range(ctx: CheckContext) -> None:
    zero_arg = lookup("sdz").arguments[0]
    k_arg = lookup("sdk").arguments[0]
    zero, k = 0, 100
    ctx.settle(ctx.frame(Command("sdz", (zero,))) + ctx.frame(Command("sdk", (k,))))
    too_big = f"#sdz.{zero_arg.maximum + 1}!#sdk.{k_arg.maximum + 1}!".encode()
    ctx.expect_no_frames(too_big, "out-of-range settings are dropped")
    expect_depth(ctx, zero, k, "after out-of-range #sdz! and #sdk!")
