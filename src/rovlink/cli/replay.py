"""Print a recording as the session it was (frames, replies with their query and round trip,
events), at once or at its recorded pace; or replay its commands to a controller at their
recorded times and compare every reply with the recorded one, printing the first differences.
Exit status with --to: 0 all replies as recorded, 1 some differ. However a replay to a controller
ends (its end, an error, Ctrl-C), #stop! is sent if its commands may have left the robot moving."""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING, cast

from rovlink.cli.failure import CommandError, UsageError
from rovlink.cli.link_options import OnOff, bounded_float, bounded_int

if TYPE_CHECKING:
    from rovlink.client import Client
    from rovlink.piloting.commanded import CommandedState
    from rovlink.protocol import Command, Response
    from rovlink.recorder import Entry

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink replay dive.mcap                       the session, line by line
  rovlink replay dive.mcap --follow --wire       at its pace, with the raw bytes
  rovlink replay dive.mcap --to 'sim://?seed=1'  resend its commands, compare the replies
  rovlink replay dive.mcap --to /dev/ttyUSB0 --speed 2 --tolerance 1"""


def _speed(text: str) -> float:
    return bounded_float(text, 0.01, 1000.0)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``replay``'s arguments."""
    parser.add_argument("file", metavar="FILE", help="a recording (.mcap or .jsonl)")
    parser.add_argument(
        "--follow", action="store_true", help="print at the recorded pace (see --speed)"
    )
    parser.add_argument(
        "--speed",
        type=_speed,
        metavar="FACTOR",
        help="pace × FACTOR (implies --follow; with --to, the commands' pace)",
    )
    parser.add_argument("--wire", action="store_true", help="print the raw bytes too")
    group = parser.add_argument_group("replaying to a controller")
    group.add_argument(
        "--to", metavar="URL", help="send the recorded commands to URL and compare the replies"
    )
    group.add_argument(
        "--checksum",
        action=OnOff,
        default=None,
        help="checksum mode of the replay (default: as the recorded driver asked for it)",
    )
    group.add_argument(
        "--tolerance",
        type=lambda text: bounded_int(text, 0, 10000),
        default=0,
        metavar="N",
        help="values within N of the recorded ones count as the same (default: %(default)s)",
    )
    group.add_argument(
        "--max-differences",
        type=lambda text: bounded_int(text, 1, 1_000_000),
        default=10,
        metavar="N",
        help="print the first N differences (default: %(default)s)",
    )


class _Damage:
    """Reads the entries, keeping the damage (if any) to report after the output."""

    def __init__(self) -> None:
        self.error: Exception | None = None

    def entries(self, path: str) -> Iterator[Entry]:
        from rovlink.recorder import RecordingDamagedError, read_entries  # noqa: PLC0415

        try:
            yield from read_entries(path)
        except RecordingDamagedError as error:
            self.error = error


def _check_kind(path: str) -> None:
    from rovlink.cli.recording import check_recording_name  # noqa: PLC0415

    kind = check_recording_name(path)
    if kind.suffix in (".bin", ".csv") and not os.path.exists(path):
        # (said before the hint, which speaks of what the file holds)
        raise CommandError(f"{path}: {os.strerror(errno.ENOENT)}")
    if kind.suffix == ".bin":
        raise CommandError(f"{path} is raw wire bytes without times: rovlink decode {path}")
    if kind.suffix == ".csv":
        raise CommandError(f"{path} holds only the telemetry table: rovlink plot {path}")


def _print_session(args: argparse.Namespace, damage: _Damage) -> None:
    from rovlink.protocol.visible import visible  # noqa: PLC0415 - only when a session is printed
    from rovlink.recorder.playback import paced, session_lines  # noqa: PLC0415

    entries = damage.entries(args.file)
    if args.follow or args.speed is not None:
        entries = paced(entries, args.speed or 1.0)
    write = sys.stdout.write
    for line in session_lines(entries, wire=args.wire):
        write(visible(line) + "\n")  # a recorded controller line may hold escapes
        if args.follow or args.speed is not None:
            sys.stdout.flush()


def _replay_to(args: argparse.Namespace, damage: _Damage) -> int:
    import rovlink  # noqa: PLC0415
    from rovlink.cli.interrupt import (  # noqa: PLC0415
        GatedClient,
        may_move,
        run_in_worker,
        say_stopped,
        suspension_refused_by,
    )
    from rovlink.cli.link_options import (  # noqa: PLC0415
        closing_unless_interrupted,
        connection_failure,
    )
    from rovlink.client.errors import ClientError, QueryTimeoutError  # noqa: PLC0415
    from rovlink.piloting.commanded import CommandedState  # noqa: PLC0415
    from rovlink.protocol import get_algorithm  # noqa: PLC0415
    from rovlink.recorder import HeaderEntry  # noqa: PLC0415
    from rovlink.recorder.comparison import (  # noqa: PLC0415
        ReplaySummary,
        drivers_checksum_mode,
        replay_steps,
        run_replay,
    )

    header: HeaderEntry | None = None
    # The mode the recording's driver asked for, as its mode frame says: its recording starts
    # plain (the connect probe, the mode frame), as its header says.
    asked_checksum: bool | None = None
    # Differences are timed as the session is listed (rovlink replay FILE): from its start.
    origin_s: float | None = None

    def scanned() -> Iterator[Entry]:
        """The entries, one at a time (an hour's recording is never held whole), noting the
        header and the start."""
        nonlocal header, origin_s, asked_checksum
        for entry in damage.entries(args.file):
            if header is None and isinstance(entry, HeaderEntry):
                header = entry
            if asked_checksum is None:
                asked_checksum = drivers_checksum_mode(entry)
            if origin_s is None and entry.t_s > 0:
                origin_s = entry.t_s
            yield entry

    steps = replay_steps(scanned())
    if args.checksum is not None:
        checksum = args.checksum
    elif asked_checksum is not None:
        checksum = asked_checksum
    else:  # (a tap's or a sniffer's recording: the mode the link was in)
        checksum = bool(header and header.checksum)
    algorithm = header.algorithm if header is not None else "crc8"
    try:
        get_algorithm(algorithm)
    except ValueError as error:  # the header damaged (or from a newer version): not --to's
        raise CommandError(f"{args.file}: the header's {error}") from None
    if not steps:
        if damage.error is not None:  # the damage, not the file, is why there is nothing
            raise CommandError(f"{damage.error}; nothing before it to replay")
        raise CommandError(f"{args.file} has no commands of a program to replay")
    to = args.to
    if to.partition(":")[0] == "sim":  # a simulated controller on the recorded algorithm
        from rovlink.sim.url import with_algorithm  # noqa: PLC0415

        try:
            to = with_algorithm(to, algorithm)
        except ValueError as error:
            raise UsageError(f"--to: {error} (the recording's)") from None
    try:
        # No motion expiry of its own: the recording holds the recorded driver's (its zero
        # thrust is replayed where it was), and one of the replay's, timed by the wall clock,
        # would fall elsewhere at another --speed, or where the recorded program (the monitor)
        # had none. The keep-alive still feeds the controller's watchdog (P17).
        client = rovlink.connect(to, checksum=checksum, algorithm=algorithm, motion_timeout=None)
    except (ConnectionError, OSError) as error:
        raise connection_failure(args.to, error) from None
    except ValueError as error:
        raise UsageError(f"--to: {error}") from None
    gate = GatedClient(client)
    # What the replayed commands left the robot in, as last sent: a recording cut mid-dive (a
    # --split part, a killed recorder) ends unlocked, and the replay must not leave it so.
    commanded = CommandedState()
    sent: list[Command] = []

    def send(command: Command) -> tuple[Response, ...] | None:
        sent.append(command)  # before it goes: a query that times out was written all the same
        commanded.apply(command)
        try:
            return cast("Client", gate).send(command)
        except QueryTimeoutError:
            return None
        except (ClientError, ConnectionError) as error:
            raise CommandError(f"{args.to}: {error}") from None

    def replay() -> ReplaySummary:
        summary = ReplaySummary()
        for step, _, divergence in run_replay(
            steps, send, speed=args.speed or 1.0, tolerance=args.tolerance, origin_s=origin_s
        ):
            summary.commands_sent += 1
            if not step.expected_count:
                continue
            summary.queries_compared += 1
            if divergence is None:
                summary.identical += 1
                continue
            summary.divergences.append(divergence)
            if len(summary.divergences) <= args.max_differences:
                print(divergence)
        return summary

    print(_announcement(args.file, args.to, [step.command for step in steps]), file=sys.stderr)
    moves = any(may_move(step.command) for step in steps)
    # (A replay that may move the robot is not suspended: see suspension_refused_by.)
    refusing = suspension_refused_by("rovlink replay") if moves else contextlib.nullcontext()
    with closing_unless_interrupted(client), refusing:
        try:
            summary = run_in_worker(replay)
        except KeyboardInterrupt:
            # The worker may be in the middle of a command: the gate makes #stop! the last
            # frame, sent as `rovlink send` does when any of its commands may move the robot.
            if moves:
                say_stopped("rovlink replay", gate.stop_for_good())
            raise
        except Exception:  # a lost link, a closed output: the worker has ended
            _stop_if_left_moving(client, commanded, sent)
            raise
        _stop_if_left_moving(client, commanded, sent)
    differing = len(summary.divergences)
    print(
        f"{summary.commands_sent} commands replayed, {summary.queries_compared} queries "
        f"compared: {summary.identical} as recorded, {differing} different"
        + (f" (first {args.max_differences} shown)" if differing > args.max_differences else "")
    )
    return 1 if differing else 0


def _announcement(path: str, url: str, commands: list[Command]) -> str:
    """What the replay is about to send, said before the first command goes: whether it
    unlocks or moves the robot, and with which commands (a controller with a robot on it).

    >>> from rovlink.protocol import Command
    >>> _announcement("d.mcap", "sim://", [Command("start"), Command("th", (0, 30)), Command("qd")])
    'replaying 3 commands of d.mcap to sim://; 2 of them unlock or move the robot (start, th)'
    >>> _announcement("d.mcap", "sim://", [Command("qd")])
    'replaying 1 command of d.mcap to sim://; none of them unlocks or moves the robot'
    """
    from rovlink.cli.interrupt import may_move  # noqa: PLC0415

    moving = [command.name for command in commands if may_move(command)]
    noun = "command" if len(commands) == 1 else "commands"
    said = f"replaying {len(commands)} {noun} of {path} to {url}"
    if not moving:
        return f"{said}; none of them unlocks or moves the robot"
    return (
        f"{said}; {len(moving)} of them unlock or move the robot "
        f"({', '.join(dict.fromkeys(moving))})"
    )


def _stop_if_left_moving(client: Client, commanded: CommandedState, sent: list[Command]) -> None:
    """Send ``#stop!`` and say so if the replayed commands may have left the robot moving: one
    of them may move it (``start``, a motion command) and the lock as last sent is not ``stop``.
    A link that is gone is said to be (the controller's link-loss watchdog stops it then)."""
    from rovlink.cli.interrupt import may_move, say_stopped, send_stop  # noqa: PLC0415
    from rovlink.piloting.commanded import LockState  # noqa: PLC0415

    if commanded.lock is LockState.LOCKED or not any(may_move(command) for command in sent):
        return
    say_stopped(
        "rovlink replay",
        send_stop(client),
        "the replayed commands may have left the robot moving",
    )


def run(args: argparse.Namespace) -> int:
    """Print or replay the recording; damage in the file is reported after what could be read."""
    from rovlink.recorder import RecordingError  # noqa: PLC0415

    _check_kind(args.file)
    damage = _Damage()
    try:
        if args.to:
            status = _replay_to(args, damage)
        else:
            _print_session(args, damage)
            status = 0
    except RecordingError as error:
        raise CommandError(str(error)) from None
    except BrokenPipeError:
        return 0
    if damage.error is not None:
        print(f"rovlink replay: {damage.error}", file=sys.stderr)
        if not getattr(damage.error, "incomplete", False):
            return 1
    return status
