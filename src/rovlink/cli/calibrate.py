"""Calibrate the depth sensor from two points: the raw pressure at the surface and at a known
depth give the depth zero (sdz) and coefficient (sdk). Each reading is the mean of several
#qr! queries. The values are shown before they are sent; --dry-run sends nothing. The two
readings must be far enough apart and the result within the command table's ranges."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.failure import CommandError, UsageError
from rovlink.cli.link_options import bounded_float, bounded_int

if TYPE_CHECKING:
    from rovlink.client import Client
    from rovlink.tuning.calibration import Calibration

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink calibrate /dev/ttyUSB0 --depth 200            asks you to place the vehicle twice
  rovlink calibrate sim:// --surface-raw 20 --depth-raw 120 --depth 200 --dry-run"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``calibrate``'s options."""
    link_options.add_link_options(parser, url_required=True)
    group = parser.add_argument_group("calibration")
    group.add_argument(
        "--depth",
        type=lambda text: bounded_int(text, 1, 9999),
        required=True,
        metavar="CM",
        help="the known depth of the second point, cm (to the pressure sensor)",
    )
    group.add_argument(
        "--surface-raw",
        type=lambda text: bounded_float(text, 0, 1024),
        metavar="RAW",
        help="the surface reading, if already known (else it is measured)",
    )
    group.add_argument(
        "--depth-raw",
        type=lambda text: bounded_float(text, 0, 1024),
        metavar="RAW",
        help="the reading at the known depth, if already known (else it is measured)",
    )
    group.add_argument(
        "--samples",
        type=lambda text: bounded_int(text, 1, 1000),
        default=20,
        metavar="N",
        help="#qr! readings averaged per point, 1–1000 (default: %(default)s)",
    )
    group.add_argument(
        "--min-counts",
        type=lambda text: bounded_float(text, 1, 1024),
        default=10,
        metavar="COUNTS",
        help="the least difference of the two readings, counts (default: %(default)s)",
    )
    group.add_argument("--dry-run", action="store_true", help="show the values, send nothing")
    group.add_argument(
        "--yes",
        action="store_true",
        help="send without asking (needed when there is no terminal to ask on); without it, "
        "any answer but y sends nothing and ends with status 1, as a no to tune or check does",
    )


def run(args: argparse.Namespace) -> int:
    """Measure (or take) both points, compute, show, and send unless --dry-run."""
    from rovlink.tuning.calibration import CalibrationError, two_point  # noqa: PLC0415

    measuring = args.surface_raw is None or args.depth_raw is None
    if measuring and not sys.stdin.isatty():
        raise UsageError(
            "measuring needs a terminal to ask on; give --surface-raw and --depth-raw instead"
        )
    given: Calibration | None = None
    if not measuring:  # nothing to read: bad readings are refused before the port opens,
        try:  # and before --yes is asked for (readings that cannot be sent, said first)
            given = two_point(args.surface_raw, args.depth_raw, args.depth, args.min_counts)
        except CalibrationError as error:
            raise CommandError(str(error)) from None
    if not (args.yes or args.dry_run or sys.stdin.isatty()):  # as tune and check --motion
        raise UsageError(
            "sending needs --yes when there is no terminal to ask on (--dry-run shows the values)"
        )
    if given is not None and args.dry_run:  # and nothing to send
        _show(given, args.depth_raw)
        print("dry run: nothing sent")
        return 0
    client = link_options.connect(args)
    try:
        surface = args.surface_raw
        if surface is None:
            _ask("Hold the vehicle with its pressure sensor at the surface, then press Enter")
            surface = _mean_raw(client, args.samples, "the surface")
            print(f"surface: raw {surface:.2f}")
        at_depth = args.depth_raw
        if at_depth is None:
            _ask(f"Lower the pressure sensor to {args.depth} cm, then press Enter")
            at_depth = _mean_raw(client, args.samples, f"at {args.depth} cm")
            print(f"at {args.depth} cm: raw {at_depth:.2f}")
        try:
            result = two_point(surface, at_depth, args.depth, args.min_counts)
        except CalibrationError as error:
            raise CommandError(str(error)) from None
        _show(result, at_depth)
        if args.dry_run:
            print("dry run: nothing sent")
            return 0
        if not args.yes and not _confirm():  # (as tune and check --motion say a no)
            raise CommandError("not confirmed; nothing was sent")
        _send(client, result)
    finally:
        client.close()
    return 0


def _show(result: Calibration, at_depth: float) -> None:
    shown_raw = round(at_depth, 2)  # (its depth from the raw shown: floored, it may differ)
    print(
        f"sdz {result.zero_raw}, sdk {result.k} ({result.cm_per_count:.2f} cm per count; "
        f"raw {shown_raw:.2f} reads as {result.depth_for(shown_raw)} cm)"
    )


def _ask(prompt: str) -> None:
    """Wait for Enter; the end of the input stops the calibration before anything is sent."""
    if link_options.ask(f"{prompt}: ") is None:
        raise CommandError("the input ended at the prompt: nothing was sent")


def _confirm() -> bool:
    return link_options.confirmed("Send these values? [y/N] ", accept=("y", "yes"))


def _send(client: Client, result: Calibration) -> None:
    """Send sdz, then sdk, then read the depth and raw reading of one ``#qsa!`` to see that
    the controller took them (the protocol acknowledges nothing, P4). A link that fails on the
    way is one line saying which values went: after sdz alone the controller is half
    calibrated."""
    from rovlink.client import ClientError  # noqa: PLC0415 - the driver loads when used

    zero, scale = f"#sdz.{result.zero_raw}!", f"#sdk.{result.k}!"
    sent: list[str] = []
    try:
        client.set_depth_zero(result.zero_raw)
        sent.append(zero)
        client.set_depth_scale(result.k)
        sent.append(scale)
        sensors = client.sensors()
    except KeyboardInterrupt:
        # (Ctrl-C or a SIGTERM taken as it: what went, before "interrupted", as for a failure)
        from rovlink.cli.interrupt import say_last  # noqa: PLC0415

        # (said if it can be: a closed terminal, SIGHUP, fails every write)
        if sent == [zero]:
            say_last(
                f"sent {zero}, interrupted while {scale} was sent: the depth zero is new and its "
                "scale may be old: calibrate again"
            )
        elif sent:
            say_last(f"sent {zero} {scale}; the depth was not read back")
        raise
    except (ClientError, TimeoutError, ConnectionError) as error:
        if not sent:
            raise CommandError(f"{error}; nothing was sent") from None
        if sent == [zero]:
            raise CommandError(
                f"sent {zero} but not {scale}: {error}; the depth zero is new and its scale "
                "old: calibrate again"
            ) from None
        raise CommandError(
            f"sent {zero} {scale}, but reading the depth back failed: {error}"
        ) from None
    depth_cm, raw = sensors.depth_cm, sensors.pressure_raw
    expected_cm = result.depth_for(raw)
    if depth_cm != expected_cm:  # (qd and qr of one qsa reply: the same reading, P12, P13)
        raise CommandError(
            f"sent {zero} {scale}, but the controller did not take them: it reads {depth_cm} cm "
            f"at raw {raw}, where they give {expected_cm} cm (P13); did it reset, or drop the "
            "frames? calibrate again"
        )
    sent_line = f"sent {zero} {scale}; depth now {depth_cm} cm (raw {raw})"
    if not result.shown_at(raw):  # (a controller that dropped them would read the same)
        sent_line += (
            f", which cannot show that the controller took them: other values read {depth_cm} "
            "cm there too; read the depth again with the sensor lower"
        )
    print(sent_line)


def _mean_raw(client: Client, samples: int, point: str) -> float:
    """The mean of ``samples`` raw readings; a link failure names the ``point`` measured."""
    import statistics  # noqa: PLC0415 - with decimal and random: not on the path of --help

    from rovlink.client import ClientError  # noqa: PLC0415 - the driver loads when used

    try:
        readings = [client.pressure_raw() for _ in range(samples)]
    except (ClientError, TimeoutError, ConnectionError) as error:
        raise CommandError(f"measuring {point}: {error}; nothing was sent") from None
    spread = max(readings) - min(readings)
    if spread > 5:  # the vehicle was moving, or the sensor is noisy: worth knowing
        print(f"  note: the readings spread over {spread} counts", file=sys.stderr)
    return statistics.fmean(readings)
