"""``--record FILE`` and the rotation options, shared by every command that records."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import stat
from typing import TYPE_CHECKING

from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, UsageError, reason
from rovlink.cli.interrupt import say_last
from rovlink.cli.link_options import DEFAULT_REPLY_TIMEOUT_S, file_name

if TYPE_CHECKING:
    from rovlink.recorder import Recorder
    from rovlink.recorder.formats import Format

__all__ = [
    "add_record_options",
    "add_rotation_options",
    "byte_size",
    "check_recording_name",
    "discard_empty_recording",
    "duration",
    "open_recorder",
    "recorded_nothing",
    "refuse_existing_recording",
    "refuse_rotation_without_record",
    "report_recording",
]

_SIZE_UNITS = {"": 1, "k": 1000, "m": 1000**2, "g": 1000**3}
#: The smallest ``--max-size``: a file must hold its header and a chunk or two.
MIN_FILE_BYTES = 4096
_TIME_UNITS = {"": 1.0, "s": 1.0, "m": 60.0, "h": 3600.0}


def byte_size(text: str) -> int:
    """A size such as ``500k``, ``100M``, ``2G`` or a number of bytes (decimal units).

    >>> byte_size("100M")
    100000000
    """
    number, unit = text[:-1] if text[-1:].isalpha() else text, text[-1:].lower()
    if not unit.isalpha():
        unit = ""
    try:
        value = float(number) * _SIZE_UNITS[unit]
        if not math.isfinite(value):  # 1e400, inf: no file is that big, and int() would fail
            raise ValueError(text)
    except (KeyError, ValueError):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a size (a number with k, M or G: 100M)"
        ) from None
    if value < MIN_FILE_BYTES:
        raise argparse.ArgumentTypeError(
            f"{text!r} is too small for a recording file: at least "
            f"{_in_unit(MIN_FILE_BYTES, text[-1:] if unit else '')}"
        )
    return int(value)


def _in_unit(size_bytes: int, unit: str) -> str:
    """``size_bytes`` exactly, and in the decimal ``unit`` as typed (``k``, ``M``...).

    >>> _in_unit(4096, "k"), _in_unit(4096, "")
    ('4096 bytes (4.096k)', '4096 bytes')
    """
    exact = f"{size_bytes} bytes"
    if not unit:
        return exact
    return f"{exact} ({size_bytes / _SIZE_UNITS[unit.lower()]:.10g}{unit})"


def duration(text: str) -> float:
    """A duration such as ``90``, ``30s``, ``10m`` or ``1h``, in seconds.

    >>> duration("10m")
    600.0
    """
    number, unit = (text[:-1], text[-1:].lower()) if text[-1:].isalpha() else (text, "")
    try:
        value = float(number) * _TIME_UNITS[unit]
    except (KeyError, ValueError):
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a duration (seconds, or with s, m or h: 10m)"
        ) from None
    if not value >= 1.0:
        raise argparse.ArgumentTypeError(f"{text!r}: a split must be at least 1 s")
    return value


def add_rotation_options(parser: argparse.ArgumentParser) -> None:
    """``--max-size`` and ``--split``: start a new file when the current one is that big or old;
    ``--overwrite``: write over a recording already there (a service that records to one name
    each time it starts)."""
    group = parser.add_argument_group("recording")
    group.add_argument(
        "--overwrite",
        action="store_true",
        help="write over a recording already there (and its rotation's files); without it, a "
        "file already there is refused",
    )
    group.add_argument(
        "--max-size",
        type=byte_size,
        metavar="SIZE",
        help="start a new file (dive.001.mcap, …) when this size is reached (e.g. 100M)",
    )
    group.add_argument(
        "--split",
        type=duration,
        metavar="DURATION",
        help="start a new file every DURATION (e.g. 10m, 1h)",
    )


def add_record_options(parser: argparse.ArgumentParser) -> None:
    """``--record FILE`` and the rotation options, for a command that drives the link."""
    parser.add_argument(
        "--record",
        type=file_name,
        metavar="FILE",
        help="record the session: every byte, frame, event and the telemetry "
        "(.mcap, .jsonl, .csv or .bin by suffix; a file already there is refused)",
    )
    add_rotation_options(parser)


def refuse_rotation_without_record(args: argparse.Namespace) -> None:
    """Refuse ``--overwrite``, ``--max-size`` and ``--split`` given without ``--record FILE``:
    they say how to record, and taken silently they would leave a team believing that a dive
    nothing records was being recorded."""
    given = [
        option
        for option, value in (
            ("--overwrite", getattr(args, "overwrite", False)),
            ("--max-size", getattr(args, "max_size", None) is not None),
            ("--split", getattr(args, "split", None) is not None),
        )
        if value
    ]
    if given:
        verb = "needs" if len(given) == 1 else "need"
        raise UsageError(f"{', '.join(given)} {verb} --record FILE: without it nothing is recorded")


def check_recording_name(path: str) -> Format:
    """The format ``path``'s suffix names; a usage error (status 2) if it names none: the
    name is what the command line got wrong, for every command given a recording's name.

    The format's module is imported now, before any link is opened: a library it needs (the
    record extra's ``mcap``) that is missing or broken is said in one line (status 1).
    """
    import importlib  # noqa: PLC0415

    from rovlink.recorder import format_of  # noqa: PLC0415

    try:
        kind = format_of(path)
    except ValueError as error:
        raise UsageError(str(error)) from None
    with needs_extra("record", f"{kind.suffix} recordings need"):
        importlib.import_module(kind.module)
    return kind


def open_recorder(
    args: argparse.Namespace, path: str, *, url: str, program: str, checksum: bool
) -> Recorder:
    """A recorder on ``path`` with the command's options; ``checksum``: the mode the link is in
    as the recording starts. A failure while recording never stops the link; the recorder
    logs it, and the command shows it where it shows the library's warnings (on stderr; in
    the dashboard and the console, which hold the terminal)."""
    from rovlink.recorder import Recorder, RecordingError  # noqa: PLC0415

    check_recording_name(path)
    refuse_existing_recording(args, path)
    if getattr(args, "overwrite", False) and _rotates(args):
        _remove_earlier_rotation(path)
    try:
        return Recorder(
            path,
            url=url,
            checksum=checksum,
            algorithm=getattr(args, "algorithm", "crc8"),
            program=program,
            max_size_bytes=args.max_size,
            split_s=args.split,
            reply_timeout_s=getattr(args, "reply_timeout_s", DEFAULT_REPLY_TIMEOUT_S),
        )
    except OSError as error:
        raise CommandError(f"cannot record to {path}: {reason(error)}") from None
    except RecordingError as error:
        raise CommandError(str(error)) from None


def _rotates(args: argparse.Namespace) -> bool:
    return args.max_size is not None or args.split is not None


def _rotation_files(path: str) -> list[str]:
    """The files of a rotation of ``path`` that are there (``dive.001.mcap``…), in order."""
    directory, name = os.path.split(path)
    stem, suffix = os.path.splitext(name)
    rotated = re.compile(rf"{re.escape(stem)}\.\d{{3,}}{re.escape(suffix)}")
    try:
        names = os.listdir(directory or ".")
    except OSError:  # (a directory that is not there: said on creation)
        return []
    return sorted(os.path.join(directory, other) for other in names if rotated.fullmatch(other))


def _remove_earlier_rotation(path: str) -> None:
    """Remove the files of an earlier rotation of ``path`` (``--overwrite``): the new recording
    writes over them as it reaches them, and those it never reaches would be taken for its
    later parts, mixing two dives."""
    for earlier in _rotation_files(path):
        try:
            os.remove(earlier)
        except FileNotFoundError:
            pass
        except OSError as error:
            raise CommandError(f"cannot record to {path}: {earlier}: {reason(error)}") from None


def refuse_existing_recording(args: argparse.Namespace, path: str) -> None:
    """Refuse to record to ``path`` if a file is there already, or (with ``--max-size`` or
    ``--split``) a file of a rotation of that name (``dive.001.mcap``): a recording is written
    over only with ``--overwrite``. It would be lost even if the new one never started, as a
    recording that holds its header alone is removed (:func:`discard_empty_recording`)."""
    if getattr(args, "overwrite", False):
        return
    taken = [path] if _holds_data(path) else []
    if _rotates(args):
        taken += _rotation_files(path)
    if taken:
        raise CommandError(
            f"cannot record to {path}: {', '.join(taken)} "
            f"{'exists' if len(taken) == 1 else 'exist'} already (a recording is "
            "never written over: remove it, record to another file, or add --overwrite)"
        )


def _holds_data(path: str) -> bool:
    """Whether writing to ``path`` would lose what is there: a file (or a link to one, or to
    nothing). A directory is no recording (its open says "Is a directory"), and a pipe that
    another program reads (``mkfifo live.jsonl``) or a device holds nothing to lose."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return os.path.lexists(path)  # (a link to nothing: it is written through)
    return stat.S_ISREG(mode)


def report_recording(recorder: Recorder, elapsed_s: float) -> None:
    """One line on stderr: what was recorded where, counted as the format holds it (an MCAP
    file's messages, a CSV's rows, a raw capture's bytes); after a failure, what was made
    durable before it."""
    held = recorder.held()
    unit = recorder.held_unit[:-1] if held == 1 else recorder.held_unit
    at_least = "at least " if recorder.error is not None else ""  # more may have reached it
    sizes = sum(os.path.getsize(path) for path in recorder.paths if os.path.exists(path))
    files = ", ".join(recorder.paths)
    lost = (
        f"; {recorder.dropped} items not recorded (the disk fell behind)"
        if recorder.dropped
        else ""
    )
    say_last(
        f"recorded {at_least}{held} {unit} in {elapsed_s:.1f} s to {files} "
        f"({sizes / 1000:.1f} kB){lost}"
    )


def recorded_nothing(recorder: Recorder) -> bool:
    """Whether the closed ``recorder``'s files hold their headers alone (each file of a rotation
    has its own), written without a failure."""
    return recorder.entries_written == len(recorder.paths) and recorder.error is None


def discard_empty_recording(recorder: Recorder, program: str) -> None:
    """Remove the files of a recording that holds its header alone (a link that did not open,
    or one that carried nothing), and say so in one line as ``program`` (``rovlink send``): a
    file that looks like a recording of a session that never took place is not left behind."""
    for path in recorder.paths:
        if _holds_data(path):  # (a pipe another program reads stays, as it was made)
            with contextlib.suppress(FileNotFoundError):
                os.remove(path)
    files = ", ".join(recorder.paths)
    say_last(f"{program}: nothing was recorded; {files} not kept")
