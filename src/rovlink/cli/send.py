"""Send commands in order and print the decoded replies.

Every command is checked before anything is sent: one that does not parse, or a raw frame the
controller would drop, is refused (status 2). A raw frame ('#qd!') goes as typed when the
controller will take it so; in checksum mode a frame typed without its checksum gets it. A
failure while sending (no reply, a lost link) exits with status 1, after #stop! once a command
that may move the robot has gone; so does a --record file that could not be written. Ctrl-C
stops at once, sending #stop! first if a command may have moved the robot. The robot is not left
driving: when the commands moved it or unlocked its motors and no stop came after, #stop! is sent
as the link closes.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import sys
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

from rovlink.cli import link_options
from rovlink.cli.failure import CommandError, UsageError
from rovlink.cli.interrupt import (
    GatedClient,
    may_move,
    run_in_worker,
    say_stopped,
    send_stop,
    suspension_refused_by,
)
from rovlink.protocol import (
    Command,
    Decoder,
    Event,
    Frame,
    Response,
    Setting,
    Text,
    UnknownCommandError,
    encode,
    lookup,
)
from rovlink.protocol.visible import visible

if TYPE_CHECKING:
    from rovlink.client import Client

__all__ = [
    "EPILOG",
    "Outgoing",
    "describe_reply",
    "group_words",
    "plan",
]

EPILOG = """\
examples:
  rovlink send sim:// start "th 270 25" qsa stop
  rovlink send /dev/ttyUSB0 --checksum qd '#qd!'     (the raw frame gets its checksum)
  rovlink send socket://robot:5760 --json qsa
  rovlink send sim:// --raw mvs -50 qd              (the exact bytes both ways)"""


def describe_reply(response: Response, frame: str | None = None) -> str:
    """A reply with its values named from the command table, e.g. ``$qd.123!  depth_cm=123``;
    ``frame``: the reply's frame as it came (with its checksum), if not the plain one.

    >>> describe_reply(Response("qro", (-1,)))
    '$qro.-1!  roll_deg=-1'
    """
    fields = "  ".join(
        f"{argument.name}={value}"
        for argument, value in zip(response.spec.arguments, response.values, strict=True)
    )
    frame = frame or str(response)
    return f"{frame}  {fields}" if fields else frame


def _reply_json(response: Response, frame: str) -> dict[str, object]:
    return {
        "frame": frame,
        "name": response.name,
        "values": {
            argument.name: value
            for argument, value in zip(response.spec.arguments, response.values, strict=True)
        },
    }


def group_words(arguments: list[str]) -> list[str]:
    """Command texts from the command line: a quoted command stays whole; unquoted words
    group as a name followed by its values, so ``th 270 25 qd`` is two commands.

    A name takes the words after it while they are numbers, and also, up to its count of
    values, words that are not a command's name: ``mvd abc`` stays one command, so that its
    error names the word that is not a number and the value it was meant for.

    >>> group_words(["th", "270", "25", "qd", "mvs -50", "#qsa!"])
    ['th 270 25', 'qd', 'mvs -50', '#qsa!']
    >>> group_words(["mvd", "abc", "th", "90", "x"])
    ['mvd abc', 'th 90 x']
    """
    groups: list[list[str]] = []
    open_group = False
    values_wanted = 0  # values the open group's command takes that it does not have yet
    for argument in arguments:
        if " " in argument.strip() or argument.startswith("#"):
            groups.append([argument])
            open_group = False
        elif open_group and (
            _NUMBER.fullmatch(argument) or (values_wanted > 0 and not _is_name(argument))
        ):
            groups[-1].append(argument)
            values_wanted -= 1
        else:
            groups.append([argument])
            open_group = True
            values_wanted = _value_count(argument)
    return [" ".join(group) for group in groups]


_NUMBER = re.compile(r"[+-]?\d+")


def _is_name(word: str) -> bool:
    """Whether ``word`` is a command's name or alias (it starts the next command)."""
    try:
        lookup(word)
    except UnknownCommandError:
        return False
    return True


def _value_count(word: str) -> int:
    """How many values the command named ``word`` takes; 0 for a word that names none."""
    try:
        return len(lookup(word).arguments)
    except UnknownCommandError:
        return 0


@dataclass(frozen=True, slots=True)
class Outgoing:
    """One command to send: the command, and the exact frame when it goes as typed."""

    command: Command
    #: A raw frame sent byte for byte; ``None``: the driver encodes ``command``.
    raw: bytes | None = None


def _decoded_command(frame: bytes, *, checksum: bool, algorithm: str) -> Command | str:
    """The command the controller takes from ``frame`` in a mode, or why it drops it."""
    events = Decoder(checksum_enabled=checksum, algorithm=algorithm).feed(frame)
    if len(events) == 1 and isinstance(events[0], Frame) and isinstance(events[0].message, Command):
        return events[0].message
    event = events[0] if events else None
    return getattr(event, "detail", None) or "not a command frame"


def _raw_outgoing(text: str, *, checksum: bool, algorithm: str) -> Outgoing:
    """A raw frame as the controller will take it in the checksum mode it will be in."""
    if not (text.isascii() and text.startswith("#") and text.endswith("!") and len(text) > 2):
        raise ValueError("a raw frame is '#', a body and '!'")
    frames = text[:-1].split("!")
    if len(frames) > 1:  # (the bytes would go as typed, the rest as line noise after the frame)
        if not all(frame.startswith("#") for frame in frames):
            raise ValueError("a raw frame is '#', a body and '!', with nothing after the '!'")
        words = " ".join(repr(f"{frame}!") for frame in frames)
        raise ValueError(
            f"more than one frame in one word: give each as a word of its own ({words})"
        )
    frame = text.encode("ascii")
    taken = _decoded_command(frame, checksum=checksum, algorithm=algorithm)
    if isinstance(taken, Command):
        return Outgoing(taken, frame)
    if checksum:  # typed without its checksum: the driver adds it
        bare = _decoded_command(frame, checksum=False, algorithm=algorithm)
        if isinstance(bare, Command):
            return Outgoing(bare)
    raise ValueError(f"the controller would drop it: {taken}")


def plan(texts: list[str], *, checksum: bool, algorithm: str) -> list[Outgoing]:
    """What to send for the command-line words, checked in the checksum mode each will meet.

    >>> [str(item.command) for item in plan(["th", "90", "5", "#qd!"], checksum=False,
    ...                                          algorithm="crc8")]
    ['#th.90.5!', '#qd!']
    """
    from rovlink.client import CommandTextError, parse_command_text  # noqa: PLC0415

    outgoing: list[Outgoing] = []
    for position, text in enumerate(group_words(texts), start=1):
        try:
            if text.startswith("#"):
                item = _raw_outgoing(text, checksum=checksum, algorithm=algorithm)
            else:
                item = Outgoing(parse_command_text(text))
        except (CommandTextError, ValueError) as error:
            raise UsageError(f"command {position} ({text!r}): {error}") from None
        setting = item.command.setting
        if setting is not None and setting[0] is Setting.CHECKSUM:
            checksum = setting[1]
        outgoing.append(item)
    return outgoing


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``send``'s arguments."""
    link_options.add_link_options(parser, url_required=True)
    parser.add_argument(
        "commands",
        metavar="COMMAND",
        nargs="+",
        help="'qd', 'th 270 25' (or th 270 25 unquoted), 'mvs -50', or a raw frame such as '#qd!'",
    )
    parser.add_argument(
        "--json",
        dest="as_json",
        action="store_true",
        help="one JSON object per command instead of text",
    )
    parser.add_argument(
        "--raw",
        action="store_true",
        help="also show the exact bytes written (>>) and read (<<); with --json as objects "
        '{"written": …} and {"read": …}',
    )


def _print_text(event: Event) -> None:
    if isinstance(event, Text):
        print(f"controller: {visible(event.text)}", file=sys.stderr, flush=True)


class _Printer:
    """Prints the bytes of a link as they go, for ``--raw``; threads print whole lines.

    It is called by the link itself, before a write and after a read: an output that cannot be
    written (``| head`` gone, a full disk) ends the showing, never the link's traffic, so that
    ``#stop!`` still goes; the command's own next line finds the output closed and ends the
    command (after ``#stop!``, where it may have moved the robot).
    """

    def __init__(self, *, as_json: bool = False) -> None:
        self._lock = threading.Lock()
        self._failed = False
        self._as_json = as_json

    def __call__(self, direction: str, data: bytes) -> None:
        with self._lock:
            if self._failed:
                return
            try:
                print(self._line(direction, data), flush=True)
            except OSError:
                self._failed = True

    def _line(self, direction: str, data: bytes) -> str:
        """``>> #qd!``; with ``--json`` a JSON object of its own, so that every line of the
        output parses: ``{"written": "#qd!"}``, ``{"read": "$qd.0!"}`` (bytes beyond ASCII as
        their Latin-1 characters)."""
        if not self._as_json:
            return f"{direction} {repr(data)[2:-1]}"
        key = "written" if direction == ">>" else "read"
        return json.dumps({key: data.decode("latin-1")})


def _send_one(client: Client, item: Outgoing) -> tuple[bytes, tuple[Response, ...]]:
    """Send one command; the frame as it went and the replies."""
    from rovlink.client import ClientError  # noqa: PLC0415

    sent = item.raw if item.raw is not None else client.frame_for(item.command)
    try:
        replies = client.send(item.command) if item.raw is None else client.send_raw(item.raw)
    except (ClientError, TimeoutError, ConnectionError) as error:
        raise CommandError(str(error)) from None
    if item.command.spec.is_query and not replies:
        raise CommandError(f"{sent.decode('ascii')}: no reply")
    return sent, replies


def _show(
    sent: bytes, replies: tuple[Response, ...], checksum: str | None, *, as_json: bool
) -> None:
    """Print a command and its replies, each reply's frame as the controller sends it, with the
    checksum of the mode in force (``checksum``: its algorithm, None when off); ``--raw`` shows
    the bytes themselves."""
    frames = [encode(reply, checksum).decode("ascii") for reply in replies]
    if as_json:
        print(
            json.dumps(
                {
                    "command": sent.decode("ascii"),
                    "replies": [_reply_json(r, f) for r, f in zip(replies, frames, strict=True)],
                },
                ensure_ascii=False,
            ),
            flush=True,
        )
        return
    print(f"> {sent.decode('ascii')}", flush=True)
    for reply, frame in zip(replies, frames, strict=True):
        print(f"< {describe_reply(reply, frame)}", flush=True)


def run(args: argparse.Namespace) -> int:
    """Send the commands in order; stop at the first failure (with ``#stop!`` once a command
    that may move the robot was sent)."""
    link_options.check_url(args)  # (a sim:// URL's algorithm is the one frames are checked with)
    outgoing = plan(args.commands, checksum=args.checksum, algorithm=args.algorithm)
    show_bytes = _Printer(as_json=args.as_json) if args.raw else None
    client = link_options.connect(args, on_stray=_print_text, show_bytes=show_bytes)
    gate = GatedClient(client)
    may_have_moved = False  # once a command that may move the robot has been sent (or tried)

    def send_all() -> None:
        nonlocal may_have_moved
        for item in outgoing:
            may_have_moved = may_have_moved or may_move(item.command)
            sent, replies = _send_one(cast("Client", gate), item)
            checksum = args.algorithm if client.checksum_enabled else None
            _show(sent, replies, checksum, as_json=args.as_json)

    moves = any(may_move(item.command) for item in outgoing)
    # (A line that may move the robot is not suspended: see suspension_refused_by.)
    refusing = suspension_refused_by("rovlink send") if moves else contextlib.nullcontext()
    with link_options.closing_unless_interrupted(client), refusing:
        try:
            run_in_worker(send_all)
        except KeyboardInterrupt:
            if moves:
                say_stopped("rovlink send", gate.stop_for_good())
            raise
        except Exception as error:  # a failed command, a lost link, a closed output (| head)
            # The rest of the line, a `stop` of the user's own among it, is not sent: a robot
            # the line set moving is not left so.
            if not may_have_moved:
                raise
            outcome = send_stop(client)
            if isinstance(error, CommandError):
                raise CommandError(f"{error} ({outcome})") from None
            say_stopped("rovlink send", outcome)
            raise
        failure = link_options.recording_failure(args)
        if failure is not None:  # a failure as any other: the robot is not left moving
            if may_have_moved:
                raise CommandError(f"{failure} ({send_stop(client)})")
            raise CommandError(failure)
    return 0
