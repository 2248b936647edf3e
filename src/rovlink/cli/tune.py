"""Tune the depth PID: a relay experiment in direct mode around a target depth (inside safe
limits) measures the ultimate gain and period; a stated rule turns them into gains on the
protocol's 0-99 scale; a depth step with those gains verifies them (overshoot, settling time,
RMS). --apply leaves the gains set if they met the verification's targets; otherwise the gains
given by --restore are sent back.
A leak, a depth past the limits, a lost link or a controller reset sends #stop! and aborts."""

from __future__ import annotations

import argparse
import math
import sys
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, UsageError
from rovlink.cli.link_options import bounded_int
from rovlink.cli.output_file import check_image_suffix, check_writable, save_figure
from rovlink.protocol import lookup

if TYPE_CHECKING:
    from rovlink.client import Client
    from rovlink.tuning import ProtocolGains, TuneResult

__all__ = ["EPILOG", "parse_triple"]

EPILOG = """\
examples:
  rovlink tune 'sim://?preset=heavy' --yes --plot tune.png
  rovlink tune /dev/ttyUSB0 --depth 150 --min-depth 50 --max-depth 300 --apply
  rovlink tune socket://robot:5760 --rule zn-no-overshoot --relay-power 20"""

#: How far inside the depth limits the verification's default step starts: its hold there is
#: approached from the target with the untried gains and overshoots on the way (6 to 10 cm
#: over 80 cm on the simulated vehicles with the simc rule, 12 to 14 cm with heave-poles), and
#: the limits abort the verification.
_STEP_MARGIN_CM = 20
#: The targets of the verification (docs/builders.md).
TARGET_OVERSHOOT_CM = 5.0
TARGET_SETTLE_S = 10.0
TARGET_RMS_CM = 2.0


def parse_triple(text: str) -> tuple[float, float, float]:
    """``A,B,C`` as three finite numbers ≥ 0, for argparse's ``type=``.

    >>> parse_triple("40,30,20")
    (40.0, 30.0, 20.0)
    """
    parts = text.split(",")
    try:
        values = tuple(float(part) for part in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(value) and value >= 0 for value in values):
        raise argparse.ArgumentTypeError(f"expected three numbers ≥ 0 as A,B,C, got {text!r}")
    return values[0], values[1], values[2]


def _scales(text: str) -> tuple[float, float, float]:
    """``--scales``: each gain is divided by its scale, so none may be 0 (or infinite)."""
    try:
        values = parse_triple(text)
    except argparse.ArgumentTypeError:
        values = (0.0, 0.0, 0.0)
    if not all(value > 0 for value in values):
        raise argparse.ArgumentTypeError(f"expected three numbers > 0 as KP,KI,KD, got {text!r}")
    return values


#: The commands that set the depth PID's gains, KP, KI, KD.
_GAIN_COMMANDS = ("mvpdp", "mvpdi", "mvpidd")


def _gains(text: str) -> tuple[int, int, int]:
    """``--restore``: gains as the protocol sends them, checked before the motors run rather
    than refused by the driver after the whole experiment."""
    gains = [lookup(name).arguments[0] for name in _GAIN_COMMANDS]
    parts = text.split(",")
    values = tuple(int(part) for part in parts if part.strip().isdigit())
    if (
        len(parts) != 3
        or len(values) != 3
        or not all(gain.check(value) for gain, value in zip(gains, values, strict=True))
    ):
        ranges = "/".join(sorted({gain.range_text() for gain in gains}))
        raise argparse.ArgumentTypeError(
            f"expected three integers {ranges} as KP,KI,KD, got {text!r}"
        )
    return values[0], values[1], values[2]


def _depth(text: str) -> int:
    """A target depth, cm, in the range of ``#mvd`` (the command table's)."""
    target = lookup("mvd").arguments[0]
    return bounded_int(text, target.minimum, target.maximum)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``tune``'s options."""
    link_options.add_link_options(parser, url_required=True)
    group = parser.add_argument_group("experiment")
    group.add_argument(
        "--depth",
        type=_depth,
        default=100,
        metavar="CM",
        help="target depth, cm, strictly between --min-depth and --max-depth "
        "(default: %(default)s)",
    )
    group.add_argument(
        "--min-depth",
        type=_depth,
        default=20,
        metavar="CM",
        help="shallowest allowed, cm (default: %(default)s)",
    )
    group.add_argument(
        "--max-depth",
        type=_depth,
        default=300,
        metavar="CM",
        help="deepest allowed, cm (default: %(default)s)",
    )
    group.add_argument(
        "--relay-power",
        type=lambda text: bounded_int(text, 5, 60),
        default=30,
        metavar="PERCENT",
        help="relay amplitude, %% vertical thrust, 5–60 (default: %(default)s)",
    )
    group.add_argument(
        "--hysteresis",
        type=lambda text: bounded_int(text, 1, 50),
        default=3,
        metavar="CM",
        help="relay hysteresis, cm, 1–50: above the sensor's noise (default: %(default)s)",
    )
    group.add_argument(
        "--rule",
        default="simc",
        metavar="RULE",
        help="tuning rule, one of --list-rules (default: %(default)s)",
    )
    group.add_argument("--list-rules", action="store_true", help="list the rules and exit")
    group.add_argument(
        "--scales",
        type=_scales,
        metavar="KP,KI,KD",
        help="the controller's gain scales ([depth_pid] kp_scale,ki_scale,kd_scale); "
        "default: the reference controller's",
    )
    group.add_argument(
        "--restore",
        type=_gains,
        metavar="KP,KI,KD",
        help="gains to send back after the verification without --apply "
        "(default: the reference controller's reset gains)",
    )
    group.add_argument(
        "--step-from",
        type=_depth,
        metavar="CM",
        help="depth the verification steps from, within the limits (default: 1 m up, at least "
        "20 cm below --min-depth; 1 m down where there is no room up)",
    )
    group.add_argument("--no-verify", action="store_true", help="skip the verification step")
    group.add_argument(
        "--apply",
        action="store_true",
        help="leave the tuned gains set, if the verification met its targets (or was skipped)",
    )
    group.add_argument(
        "--plot",
        type=link_options.file_name,
        metavar="FILE",
        help="plot the relay and the step (matplotlib)",
    )
    group.add_argument("--yes", action="store_true", help="do not ask before the motors run")


def run(args: argparse.Namespace) -> int:
    """Run the autotune; 1 if the verification misses a target."""
    from rovlink.controller.config import DepthPidConfig  # noqa: PLC0415
    from rovlink.tuning import (  # noqa: PLC0415
        RULES,
        DepthLimits,
        GainScales,
        Plant,
        ProtocolGains,
        RelaySettings,
        StepSettings,
        TuneAbortedError,
        autotune,
    )

    if args.list_rules:
        for name, rule in RULES.items():
            print(f"{name:18} {rule.description}")
        return 0
    if args.rule not in RULES:
        raise UsageError(f"--rule: unknown rule {args.rule!r}; known: {', '.join(RULES)}")
    rule = RULES[args.rule]
    try:
        limits = DepthLimits(args.min_depth, args.max_depth)
    except ValueError as error:
        raise UsageError(str(error)) from None
    # Strictly: the relay swings around the target, and the plant aborts past either limit.
    if not args.min_depth < args.depth < args.max_depth:
        raise UsageError(
            f"--depth {args.depth} must lie strictly between --min-depth {args.min_depth} "
            f"and --max-depth {args.max_depth}"
        )
    _check_relay_fits(args)
    _check_real_time(args.url)
    defaults = DepthPidConfig()
    scales = GainScales(*(args.scales or (defaults.kp_scale, defaults.ki_scale, defaults.kd_scale)))
    kp, ki, kd = args.restore or (defaults.kp, defaults.ki, defaults.kd)
    restore = ProtocolGains(kp, ki, kd)
    step = None if args.no_verify else StepSettings(from_cm=_step_from(args), to_cm=args.depth)
    if args.plot:
        _check_plot(args.plot)
    if not args.yes and not _confirm(args):
        raise CommandError("not confirmed; nothing was sent")
    from rovlink.cli.interrupt import suspension_refused_by  # noqa: PLC0415

    client = link_options.connect(args)
    try:
        plant = Plant(client, limits)
        relay = RelaySettings(
            target_cm=args.depth,
            amplitude_percent=args.relay_power,
            hysteresis_cm=args.hysteresis,
        )
        try:
            with suspension_refused_by("rovlink tune"):  # (the motors run: not suspended)
                result = autotune(plant, relay, rule, scales, step, progress=_progress)
        except TuneAbortedError as error:
            raise CommandError(f"aborted: {error}{_gains_back(client, restore)}") from None
        except KeyboardInterrupt:
            # What became of the motors and the gains, before "interrupted": the operator
            # pressed Ctrl-C to stop a running experiment and is told that it did.
            from rovlink.cli.interrupt import say_last  # noqa: PLC0415

            # (said if it can be: a closed terminal, SIGHUP, fails every write)
            say_last(f"{plant.stop()}{_gains_back(client, restore)}")
            raise
        # Gains the verification found wanting are not left set, --apply or not: they may
        # hold the depth worse than the ones they would replace.
        met = result.step is None or _meets_targets(result)
        applied = args.apply and met
        final = result.gains if applied else restore
        _send_gains(client, final)
    finally:
        client.close()
    _print(result, applied, final, refused=args.apply and not met)
    if args.plot:
        _plot(result, args.plot)
    return 0 if met else 1


def _progress(line: str) -> None:
    """What the experiment is doing, on stderr as it starts (it runs for minutes with the motors
    on; the result goes to stdout at the end)."""
    print(line, file=sys.stderr, flush=True)


def _check_relay_fits(args: argparse.Namespace) -> None:
    """Refuse a relay whose switching depths are not inside the limits: the relay turns only
    once the depth is past --depth ± --hysteresis, so the vehicle would run to a limit and the
    experiment abort there, every time, after the motors had run."""
    shallow, deep = args.depth - args.hysteresis, args.depth + args.hysteresis
    if not (args.min_depth < shallow and deep < args.max_depth):
        raise UsageError(
            f"--depth {args.depth} ± --hysteresis {args.hysteresis} (the relay switches past "
            f"{shallow} and {deep} cm) must lie strictly between --min-depth {args.min_depth} "
            f"and --max-depth {args.max_depth}"
        )


def _check_real_time(url: str) -> None:
    """Refuse a simulator that runs faster than real time: the experiment is paced by the wall
    clock, so between two samples the simulated controller saw no frame for seconds, and its
    link-loss failsafe (P17) locked the motors; the relay then ran to its timeout."""
    simulated = url
    if url.startswith("fault:"):  # (a noisy link to a simulator: the same clock within)
        from rovlink.faults.settings import parse_fault_url  # noqa: PLC0415

        try:
            simulated, _ = parse_fault_url(url)
        except ValueError:
            return
    if not simulated.startswith("sim:"):
        return
    from rovlink.sim.url import parse_sim_url  # noqa: PLC0415 - only for a sim:// URL

    try:
        realtime = parse_sim_url(simulated).realtime
    except ValueError:
        return  # (opening the URL says what is wrong with it)
    if not realtime:
        raise UsageError(
            f"{url}: realtime=0 runs the simulation faster than the tune's clock, and its "
            "link-loss failsafe (P17) locks the motors between two samples; leave realtime on"
        )


def _step_from(args: argparse.Namespace) -> int:
    """The depth the verification steps from: given, or 1 m above the target but at least
    _STEP_MARGIN_CM below --min-depth (or, with no room there, 1 m below the target, at least
    as far above --max-depth); refused outside the limits before anything is sent, as the step
    drives there."""
    if args.step_from is None:
        depth, shallowest, deepest = int(args.depth), int(args.min_depth), int(args.max_depth)
        above = max(depth - 100, shallowest + _STEP_MARGIN_CM)
        if above < depth:
            return above
        below = min(depth + 100, deepest - _STEP_MARGIN_CM)
        if below > depth:
            return below
        raise UsageError(
            f"--depth {depth} leaves no room for the verification's step {_STEP_MARGIN_CM} cm "
            f"inside --min-depth {shallowest} and --max-depth {deepest} (the hold it starts "
            "from overshoots): give --step-from, or --no-verify"
        )
    if not args.min_depth <= args.step_from <= args.max_depth:
        raise UsageError(
            f"--step-from {args.step_from} must lie between --min-depth {args.min_depth} "
            f"and --max-depth {args.max_depth}"
        )
    if args.step_from == args.depth:
        raise UsageError(f"--step-from {args.step_from} is --depth: the step would not move")
    return int(args.step_from)


def _gains_back(client: Client, restore: ProtocolGains) -> str:
    """After an aborted experiment, send the ``--restore`` gains back, as a finished one does
    without --apply: an abort during the verification left its untried gains set. What became
    of them, for the abort's line."""
    from rovlink.client import ClientError, operations  # noqa: PLC0415

    try:
        for command in operations.depth_pid(restore.kp, restore.ki, restore.kd):
            client.send(command)
    except (ClientError, ConnectionError):
        # (the link's failure is the abort's reason, said before this)
        return "; the gains could not be sent back (the link failed): set them"
    return f"; gains sent back: mvpdp {restore.kp}, mvpdi {restore.ki}, mvpidd {restore.kd}"


def _send_gains(client: Client, gains: ProtocolGains) -> None:
    """Send the gains to leave set, one frame at a time: a link lost on the way is one line
    saying which went (the experiment's own ``#stop!`` has gone before)."""
    from rovlink.client import ClientError, operations  # noqa: PLC0415

    sent: list[str] = []
    for command in operations.depth_pid(gains.kp, gains.ki, gains.kd):
        went = f"only {' '.join(sent)} went" if sent else "none went"
        try:
            client.send(command)
        except KeyboardInterrupt:
            # (Ctrl-C or a SIGTERM taken as it: which gains went, before "interrupted")
            from rovlink.cli.interrupt import say_last  # noqa: PLC0415

            say_last(
                f"interrupted while {command} was sent ({went} before it; the depth PID may not "
                "be as asked: tune again or set it)"
            )
            raise
        except (ClientError, ConnectionError) as error:
            raise CommandError(
                f"the experiment ended, but {command} could not be sent ({went}; the depth "
                f"PID is not as asked: tune again or set it): {error}"
            ) from None
        sent.append(str(command))


def _confirm(args: argparse.Namespace) -> bool:
    if not sys.stdin.isatty():
        raise UsageError("tune runs the motors: --yes is needed when there is no terminal")
    # The relay swings ±relay_power around a bias that it moves to the hull's trim, held
    # within ±relay_power: the thrust goes up to twice the relay's power (45 % on the heavy
    # simulated hull at 30 %), which the prompt said was the most.
    print(
        f"The autotune unlocks the motors and drives the vertical thrusters at ±"
        f"{args.relay_power} % around the thrust that holds the vehicle still (its trim, found "
        f"as it runs), up to {min(100, 2 * args.relay_power)} %, around {args.depth} cm (limits "
        f"{args.min_depth}–{args.max_depth} cm). The vehicle must be in water and free to move.",
        file=sys.stderr,
    )
    return link_options.confirmed("Type yes to go on: ")


def _meets_targets(result: TuneResult) -> bool:
    assert result.step is not None
    metrics = result.step.measured
    return (
        metrics.overshoot_cm <= TARGET_OVERSHOOT_CM
        and metrics.settling_s <= TARGET_SETTLE_S
        and metrics.rms_cm <= TARGET_RMS_CM
    )


def _print(result: TuneResult, applied: bool, final: ProtocolGains, *, refused: bool) -> None:
    relay = result.relay
    physical = result.physical
    gains = result.gains
    print(
        f"relay:  ultimate gain Ku {relay.ultimate_gain:.3f} %/cm, ultimate period Tu "
        f"{relay.ultimate_period_s:.2f} s (amplitude {relay.amplitude_cm:.1f} cm, "
        f"trim {relay.bias_percent:+.1f} %)"
    )
    print(f"rule:   {result.rule.name}: {result.rule.description}")
    print(
        f"gains:  Kp {physical.kp:.3f} %/cm, Ki {physical.ki:.4f} %/(cm·s), "
        f"Kd {physical.kd:.3f} %/(cm/s) -> mvpdp {gains.kp}, mvpdi {gains.ki}, "
        f"mvpidd {gains.kd}"
        + (f" ({', '.join(gains.saturated)} held at the range's end)" if gains.saturated else "")
    )
    if result.step is not None:
        metrics = result.step.measured
        settings = result.step.settings
        print(
            f"verify: step {settings.from_cm} -> {settings.to_cm} cm (measured depth, mean over "
            f"{settings.smooth_s:g} s): "
            f"overshoot {metrics.overshoot_cm:.1f} cm (target ≤ {TARGET_OVERSHOOT_CM:g}), "
            f"within ±{settings.band_cm:g} cm after {metrics.settling_s:.1f} s "
            f"(target ≤ {TARGET_SETTLE_S:g}), RMS {metrics.rms_cm:.2f} cm over the minute after "
            f"(target ≤ {TARGET_RMS_CM:g})"
        )
    sent = f"mvpdp {final.kp}, mvpdi {final.ki}, mvpidd {final.kd}"
    why = " (--apply: the verification missed a target)" if refused else ""
    state = "applied" if applied else f"not applied{why}; sent back {sent}"
    print(f"gains {state}; motors locked")


def _check_plot(path: str) -> None:
    """Refuse a ``--plot`` that could not be written before the motors run, not after the
    experiment: matplotlib missing, a name without an image suffix, a directory not there."""
    with needs_extra("plot", "--plot needs"):
        import matplotlib  # noqa: PLC0415, F401 - the plot extra, only with --plot
    check_image_suffix("--plot", path)
    check_writable("--plot", path)


def _plot(result: TuneResult, path: str) -> None:
    import matplotlib  # noqa: PLC0415 - found by _check_plot before the experiment

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    rows = 2 if result.step is not None else 1
    figure, axes = plt.subplots(rows, 1, figsize=(8, 3.2 * rows), squeeze=False)
    relay = result.relay
    top = axes[0][0]
    top.plot(relay.times_s, relay.depths_cm, label="depth (qd), cm")
    thrust = top.twinx()
    thrust.plot(relay.times_s, relay.outputs_percent, color="tab:orange", alpha=0.7)
    thrust.set_ylabel("relay thrust, % (+ up)", color="tab:orange")
    top.set_title(f"relay: Ku {relay.ultimate_gain:.2f} %/cm, Tu {relay.ultimate_period_s:.2f} s")
    top.set_xlabel("s")
    top.set_ylabel("depth (qd), cm")
    top.invert_yaxis()
    if result.step is not None:
        step = result.step
        bottom = axes[1][0]
        bottom.plot(step.times_s, step.depths_cm, label="depth (qd), cm")
        bottom.plot(
            step.times_s,
            step.smoothed_depths_cm,
            label=f"qd, mean over {step.settings.smooth_s:g} s (judged)",
        )
        if step.true_depths_cm:
            bottom.plot(step.times_s, step.true_depths_cm, label="true depth, cm")
        target = step.settings.to_cm
        band = step.settings.band_cm
        bottom.axhspan(target - band, target + band, alpha=0.2, label=f"±{band:g} cm")
        bottom.set_title(
            f"verification: gains {result.gains.kp} {result.gains.ki} {result.gains.kd}"
        )
        bottom.set_xlabel("s after the step")
        bottom.invert_yaxis()
        bottom.legend(loc="best")
    figure.tight_layout()
    try:
        save_figure(figure, path)
    finally:
        plt.close(figure)
