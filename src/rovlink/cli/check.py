"""Check that a controller conforms to the protocol: every command and every decision a host can
observe, each a named check. Prints a pass/fail table with the bytes that show each failure, and
exits with status 1 if any check failed.

The run writes settings it cannot read back (max PWM, PID gains, sdz, sdk, all at their lowest
or test values): reset the controller afterwards. Motion checks drive the vertical thrusters at
low power and run only with --motion (after a prompt, unless --yes); a leak or a lost link sends
#stop! and aborts."""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from rovlink.cli.failure import CommandError, UsageError, reason
from rovlink.cli.link_options import (
    GivenAlgorithm,
    agree_on_algorithm_with_simulator,
    algorithm_name,
    bounded_int,
    confirmed,
    file_name,
    seconds,
)
from rovlink.cli.output_file import check_writable

if TYPE_CHECKING:
    from rovlink.client.url import Endpoint
    from rovlink.conformance import Check, CheckResult, Report

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink check sim://                          the simulator: everything passes
  rovlink check /dev/ttyUSB0 --junit check.xml  for a firmware CI
  rovlink check /dev/ttyACM0 --motion --yes     the motion checks too, no prompt
  rovlink check --list                          every check and the rules it covers"""

_MAX_MOTION_PERCENT = 50


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``check``'s options."""
    parser.add_argument(
        "url",
        nargs="?",
        metavar="URL",
        help="the controller's serial device or URL (socket://HOST:PORT, sim://); needed "
        "unless --list",
    )
    parser.add_argument(
        "--list", action="store_true", help="list the checks (those --only selects) and exit"
    )
    parser.add_argument(
        "--only",
        action="append",
        metavar="NAME",
        default=[],
        help="run only checks whose name starts with NAME (repeatable)",
    )
    parser.add_argument(
        "--junit", type=file_name, metavar="FILE", help="also write the results as JUnit XML"
    )
    parser.add_argument(
        "--algorithm",
        type=algorithm_name,
        action=GivenAlgorithm,
        default="crc8",
        metavar="NAME",
        help="the controller's checksum algorithm (default: %(default)s); a sim:// "
        "controller is given it",
    )
    parser.add_argument(
        "--timeout",
        type=lambda text: seconds(text, minimum=0.01, maximum=10.0),
        default=0.25,
        metavar="SECONDS",
        help="how long to wait for a reply before calling it missing, 0.01–10 "
        "(default: %(default)s)",
    )
    parser.add_argument(
        "--motion", action="store_true", help="also run the motion checks (the thrusters turn)"
    )
    parser.add_argument(
        "--motion-power",
        type=lambda text: bounded_int(text, 5, _MAX_MOTION_PERCENT),
        default=30,
        metavar="PERCENT",
        help=f"vertical thrust of the motion checks, %%, 5–{_MAX_MOTION_PERCENT} "
        "(default: %(default)s)",
    )
    parser.add_argument(
        "--watchdog",
        type=lambda text: seconds(text, minimum=0.1, maximum=60.0),
        default=2.0,
        metavar="SECONDS",
        help="the controller's link-loss watchdog, for the failsafe check, 0.1–60 (default: 2)",
    )
    parser.add_argument("--yes", action="store_true", help="do not ask before motion checks")
    parser.add_argument("--seed", type=int, default=1, help="seed of the noise sent (default: 1)")


def run(args: argparse.Namespace) -> int:
    """Run the suite and print the table; 1 if any check failed."""
    from rovlink.client.errors import ConnectError  # noqa: PLC0415
    from rovlink.client.links import open_link  # noqa: PLC0415
    from rovlink.client.url import parse_url  # noqa: PLC0415
    from rovlink.conformance import (  # noqa: PLC0415
        PreflightError,
        SuiteOptions,
        run_checks,
        select_checks,
        write_junit,
    )

    if args.list:  # (what --only selects, motion checks included: a list runs nothing)
        try:
            listed = select_checks(args.only, motion=True)
        except ValueError as error:
            raise UsageError(str(error)) from None
        _print_list(listed)
        return 0
    if args.url is None:
        raise UsageError("the controller's URL is required (or --list)")
    try:
        checks = select_checks(args.only, motion=args.motion)
        endpoint = parse_url(args.url)
    except ValueError as error:
        raise UsageError(str(error)) from None
    agree_on_algorithm_with_simulator(args)  # (a simulated controller: in the one asked)
    endpoint = parse_url(args.url)
    if args.junit:
        check_writable("--junit", args.junit)
    # Asked only when a check that runs moves the robot: --motion with --only query-… moves
    # nothing, and needs neither an answer nor --yes.
    moves = any(check.motion for check in checks)
    if moves and not args.yes and not _confirm_motion(args.motion_power):
        raise CommandError("motion checks not confirmed; nothing was sent")
    options = SuiteOptions(
        algorithm=args.algorithm,
        reply_timeout_s=args.timeout,
        motion=args.motion,
        motion_percent=args.motion_power,
        watchdog_s=args.watchdog,
        baudrate=_line_rate(endpoint),
        seed=args.seed,
    )
    try:
        link = open_link(endpoint)
    except ConnectError as error:
        _not_started(args, str(error))
    done: list[CheckResult] = []

    def on_result(result: CheckResult) -> None:
        done.append(result)
        _progress(result)

    from rovlink.cli.interrupt import suspension_refused_by  # noqa: PLC0415

    # (Motion checks are not suspended: see suspension_refused_by.)
    refusing = suspension_refused_by("rovlink check") if moves else contextlib.nullcontext()
    started_s = time.monotonic()
    try:
        with refusing:
            report = run_checks(link, args.url, options, checks, on_result=on_result)
    except PreflightError as error:
        _not_started(args, f"{args.url}: {error}")
    except KeyboardInterrupt:  # (Ctrl-C, or a CI's timeout: SIGTERM)
        if args.junit:
            _write_interrupted(args.junit, args.url, checks, done, time.monotonic() - started_s)
        raise
    finally:
        link.close()
    _print_report(report, motion_not_run=0 if args.motion else _motion_checks(args.only))
    if args.junit:
        try:
            write_junit(report, args.junit)
        except OSError as error:
            raise CommandError(f"cannot write {args.junit}: {reason(error)}") from None
    return 0 if report.passed else 1


def _line_rate(endpoint: Endpoint) -> int | None:
    """The rate of the serial line the controller's bytes cross, for the reply-time allowance
    (P19 counts from the query's arrival); None where no line is crossed: a URL (TCP,
    ``sim://``) or a pseudo-terminal, whose bytes arrive at once whatever its baud rate (a
    simulator's, or a firmware's host build's: given the line's time, a reply 0.9 ms late
    passed at 115200 baud)."""
    if not endpoint.is_device:
        return None
    path = os.path.realpath(endpoint.target)
    if path.startswith("/dev/pts/") or re.fullmatch(r"/dev/ttys\d+", path):  # (Linux, macOS)
        return None
    return endpoint.baudrate


def _write_interrupted(
    path: str, target: str, checks: list[Check], done: list[CheckResult], duration_s: float
) -> None:
    """The ``--junit`` file of an interrupted run that lasted ``duration_s``: the checks that
    ended, one case in error saying so, and the rest not run (left as an earlier run wrote it,
    a CI would read that run's results as this one's)."""
    from rovlink.conformance import Report, write_junit  # noqa: PLC0415

    names = {result.name for result in done}
    report = Report(
        target,
        list(done),
        duration_s=duration_s,
        not_run=[check.name for check in checks if check.name not in names],
        cut_short_by="the run was interrupted (Ctrl-C or a signal)",
    )
    with contextlib.suppress(OSError):  # (the interruption is what the command reports)
        write_junit(report, path)


def _not_started(args: argparse.Namespace, why: str) -> NoReturn:
    """End a run that could not start with ``why``; with ``--junit``, its file says so (left
    as an earlier run wrote it, a CI would read that run's results as this one's)."""
    from rovlink.conformance.junit import junit_not_started  # noqa: PLC0415

    if args.junit:
        try:
            Path(args.junit).write_bytes(junit_not_started(args.url, why) + b"\n")
        except OSError as error:
            why += f"; cannot write {args.junit}: {reason(error)}"
    raise CommandError(why)


def _confirm_motion(percent: int) -> bool:
    if not sys.stdin.isatty():
        raise UsageError("--motion needs --yes when there is no terminal to ask on")
    print(
        f"The motion checks unlock the motors and drive the vertical thrusters at {percent} % "
        "down for a few seconds. The vehicle must be in water and free to move.",
        file=sys.stderr,
    )
    return confirmed("Type yes to go on: ")


def _progress(result: CheckResult) -> None:
    print(f"  {result.outcome.value:5} {result.name}", file=sys.stderr, flush=True)


def _print_list(checks: list[Check]) -> None:
    from rich.table import Table  # noqa: PLC0415

    from rovlink.cli.rich_console import TableConsole  # noqa: PLC0415

    table = Table("check", "rules", "what it shows", box=None)
    for item in checks:
        label = item.name + (" (--motion)" if item.motion else "")
        table.add_row(label, " ".join(item.rules), item.description)
    TableConsole().print(table)


def _motion_checks(names: list[str] | None) -> int:
    """How many motion checks the selection would have run with --motion."""
    from rovlink.conformance import select_checks  # noqa: PLC0415

    return sum(item.motion for item in select_checks(names or (), motion=True))


def _print_report(report: Report, *, motion_not_run: int = 0) -> None:
    from rich.markup import escape  # noqa: PLC0415
    from rich.table import Table  # noqa: PLC0415

    from rovlink.cli.rich_console import TableConsole  # noqa: PLC0415
    from rovlink.conformance import Outcome  # noqa: PLC0415
    from rovlink.conformance.junit import evidence_text  # noqa: PLC0415
    from rovlink.conformance.lock import STOP_LOCKS_CHECK  # noqa: PLC0415

    console = TableConsole()
    table = Table("result", "check", "rules", "ms", box=None)
    colours = {"pass": "green", "fail": "red", "abort": "red", "skip": "yellow"}
    for result in report.results:
        value = result.outcome.value
        table.add_row(
            f"[{colours[value]}]{value}[/]",
            result.name,
            " ".join(result.rules),
            f"{result.duration_s * 1000:.0f}",
        )
    console.print(table)
    for result in report.failures:
        console.print(
            f"\n[red]{result.outcome.value}[/] [bold]{result.name}[/]: {escape(result.message)}"
        )
        console.print(escape(evidence_text(result.evidence, 4)), highlight=False)
    if report.hint is not None:
        console.print(f"\n[yellow]hint[/]: {escape(report.hint)}")
    if report.settings_sent:
        console.print(
            f"\nthe checks set {', '.join(report.settings_sent)} to test values, which no query "
            "reads back: reset the controller (or set them again) before using it"
        )
    # Skipped, the check that sees #stop! lock without motion leaves #stop! unverified: said
    # in words, not left to a "skip" in the table.
    stop_unverified = [
        result
        for result in report.results
        if result.name == STOP_LOCKS_CHECK and result.outcome is Outcome.SKIPPED
    ]
    for result in stop_unverified:
        console.print(
            f"\n[yellow]skip[/] [bold]{STOP_LOCKS_CHECK}[/]: {escape(result.message)}; no other "
            "check without --motion shows that #stop! locks the motors"
        )
    passed = report.count(Outcome.PASSED)
    aborted = (
        f"; {len(report.not_run)} more not run: {report.stopped_because}" if report.not_run else ""
    )
    console.print(
        f"\n{report.target}: {passed} of {len(report.results)} checks passed "
        f"in {report.duration_s:.1f} s"
        + aborted
        + ("; #stop! NOT verified" if stop_unverified else "")
        + (
            f"; {motion_not_run} motion checks (#stop!, the link-loss failsafe) not run: "
            "add --motion"
            if motion_not_run
            else ""
        )
    )
