"""What a console line asks for: a command for the robot (read by the driver's command-text
parser) or one of the console's own words (``help``, ``checksum on``, ``raw``, ``status``,
``quit``). Bad input raises :class:`InputError` with the position of the culprit in the line,
so the prompt can put the cursor there; nothing is sent.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from rovlink.client import CommandTextError, parse_command_text, usage
from rovlink.client.command_text import is_command_name, unknown_command_text
from rovlink.protocol import BadFrame, Command, Decoder, Frame, Reason, lookup

__all__ = [
    "BUILTINS",
    "Action",
    "Builtin",
    "InputError",
    "Quit",
    "SendCommand",
    "SendRaw",
    "SetChecksum",
    "ShowHelp",
    "ShowStatus",
    "parse_line",
    "parse_lines",
]

_WORD = re.compile(r"[^\s,]+")
#: A whole frame, as copied from a capture or a log: several on a line run one after another.
_FRAME = re.compile(r"#[^#!\s]*!")
_FRAMES_ONLY = re.compile(r"\s*(?:#[^#!\s]*!\s*){2,}")
#: A first word that can only be a name (not a frame, nor a body such as th.90.30).
_WORD_NAME = re.compile(r"[^#.!]+")


@dataclass(frozen=True, slots=True)
class Builtin:
    """One of the console's own words."""

    name: str
    usage: str
    description: str


#: The console's own words, for help and completion (the robot's commands come from the table).
BUILTINS: tuple[Builtin, ...] = (
    Builtin("help", "help [COMMAND]", "list every command, or show one with its arguments"),
    Builtin("checksum", "checksum on|off", "turn checksum mode on or off (#crcon! / #crcoff!)"),
    Builtin("raw", "raw FRAME", "send FRAME exactly as typed, unchecked (e.g. raw #bogus!)"),
    Builtin("status", "status", "the state as last sent and the link's figures"),
    Builtin(
        "quit", "quit", "leave (sends #stop! first unless locked as last sent); also exit, Ctrl-D"
    ),
)
_BUILTIN_NAMES = frozenset(builtin.name for builtin in BUILTINS) | {"exit"}


@dataclass(frozen=True, slots=True)
class SendCommand:
    """Send a command of the table (the driver adds the checksum when the mode is on)."""

    command: Command


@dataclass(frozen=True, slots=True)
class SendRaw:
    """Send a frame exactly as typed."""

    frame: str


@dataclass(frozen=True, slots=True)
class ShowHelp:
    """List the commands, or show one."""

    name: str | None = None


@dataclass(frozen=True, slots=True)
class SetChecksum:
    """Checksum mode on or off."""

    enabled: bool


@dataclass(frozen=True, slots=True)
class ShowStatus:
    """Show the state as last sent and the link's figures."""


@dataclass(frozen=True, slots=True)
class Quit:
    """Leave the console."""


Action = SendCommand | SendRaw | ShowHelp | SetChecksum | ShowStatus | Quit


class InputError(ValueError):
    """A line that is not valid input; ``position`` is where in the line the problem is."""

    def __init__(self, message: str, position: int) -> None:
        super().__init__(message)
        self.message = message
        self.position = position


def parse_line(line: str, checksum: str | None = None) -> Action | None:
    """The action a console line asks for; ``None`` for a blank line. ``checksum``: the
    algorithm while checksum mode is on, so that a frame typed with its checksum is taken.

    >>> parse_line("th 270 25")
    SendCommand(command=Command(name='th', values=(270, 25)))
    >>> parse_line("checksum on")
    SetChecksum(enabled=True)
    >>> try:
    ...     parse_line("th 400 25")
    ... except InputError as error:
    ...     print(error.position, error)
    3 th: direction_deg must be in 0–360, got 400
    """
    words = list(_WORD.finditer(line))
    if not words:
        return None
    first = words[0].group()
    if first in _BUILTIN_NAMES:
        return _builtin(line, first, words)
    if _WORD_NAME.fullmatch(first) and not is_command_name(first):
        # (Named among the console's own words too: a typo of "status" is not "start"'s.)
        raise InputError(unknown_command_text(first, _BUILTIN_NAMES), words[0].start())
    try:
        return SendCommand(parse_command_text(line))
    except CommandTextError as error:
        if checksum is not None:
            command = _checksummed_frame(line, checksum)
            if command is not None:
                return SendCommand(command)
        raise InputError(str(error), _error_position(line, error)) from None


def parse_lines(text: str, checksum: str | None = None) -> list[Action]:
    """The actions of every line of ``text``, in order: pasted lines run one after another, as
    if typed one by one, and so do the frames of a line of frames alone (``#start!#qd!``).
    All are checked before any runs: one bad line refuses the whole text, its error naming the
    line and pointing into it.

    >>> parse_lines("start\\nth 0 50\\n\\nqd")  # doctest: +NORMALIZE_WHITESPACE
    [SendCommand(command=Command(name='start', values=())),
     SendCommand(command=Command(name='th', values=(0, 50))),
     SendCommand(command=Command(name='qd', values=()))]
    >>> try:
    ...     parse_lines("start\\nth 0 500")
    ... except InputError as error:
    ...     print(error.position, error)
    11 line 2: th: power_percent must be in 0–100, got 500
    """
    lines = text.split("\n")
    several = sum(1 for line in lines if line.strip()) > 1
    actions: list[Action] = []
    offset = 0
    for number, line in enumerate(lines, start=1):
        for start, part in _parts(line.removesuffix("\r")):
            try:
                action = parse_line(part, checksum)
            except InputError as error:
                message = f"line {number}: {error.message}" if several else error.message
                raise InputError(message, offset + start + error.position) from None
            if action is not None:
                actions.append(action)
        offset += len(line) + 1
    return actions


def _parts(line: str) -> list[tuple[int, str]]:
    """The line, or each frame of a line of frames alone (``#start!#th.90.30!``), with where
    in the line it starts. A line that begins with a whole frame and goes on with something
    else (``#qd!$qd.5!``, ``#qd!!``) is refused, pointing at what is not a frame."""
    if _FRAMES_ONLY.fullmatch(line) is not None:
        return [(frame.start(), frame.group()) for frame in _FRAME.finditer(line)]
    first = _FRAME.search(line)
    if first is None:
        return [(0, line)]
    before = line[: first.start()]
    if before.strip():
        if not before.lstrip().startswith("#"):  # (words: the command parser says what is wrong)
            return [(0, line)]
        position = len(before) - len(before.lstrip())  # (##qd!, #th.90 #qd!)
        raise InputError(_not_a_frame(before.split(maxsplit=1)[0]), position)
    if not line[first.end() :].strip():
        return [(0, line)]
    frames_end = first.end()
    for frame in _FRAME.finditer(line, first.end()):
        if line[frames_end : frame.start()].strip():
            break
        frames_end = frame.end()
    rest = line[frames_end:]
    position = frames_end + len(rest) - len(rest.lstrip())
    raise InputError(_not_a_frame(line[position:].split(maxsplit=1)[0]), position)


def _not_a_frame(text: str) -> str:
    return f"not a whole frame: {text!r} (frames on one line are each #…!, e.g. #start!#qd!)"


def _checksummed_frame(line: str, algorithm: str) -> Command | None:
    """The command of a frame typed with its checksum (``#qd8C!``), as the controller reads it
    in checksum mode; ``None`` if the line is not such a frame. A frame with a wrong checksum
    is an error that says so."""
    stripped = line.strip()
    if not (stripped.startswith("#") and stripped.endswith("!") and stripped.isascii()):
        return None
    events = Decoder(checksum_enabled=True, algorithm=algorithm).feed(stripped.encode("ascii"))
    if len(events) != 1:
        return None
    event = events[0]
    if isinstance(event, BadFrame) and event.reason is Reason.CHECKSUM:
        # (a body the parser took for values, e.g. 25CA, is what a wrong checksum looks like)
        raise InputError(f"{event.detail}", line.index(stripped) + len(stripped) - 3)
    if isinstance(event, Frame) and isinstance(event.message, Command):
        return event.message
    return None


def _builtin(line: str, name: str, words: list[re.Match[str]]) -> Action:
    arguments = [word.group() for word in words[1:]]
    if name in ("quit", "exit", "status"):
        if arguments:
            raise InputError(f"{name} takes nothing after it", words[1].start())
        return Quit() if name != "status" else ShowStatus()
    if name == "help":
        if len(arguments) > 1:
            raise InputError("help takes at most one command name", words[2].start())
        if not arguments:
            return ShowHelp()
        topic = arguments[0].lstrip("#").rstrip("!")
        if topic == "exit":  # (quit's other name: its help is quit's)
            topic = "quit"
        if topic not in _BUILTIN_NAMES:
            if _WORD_NAME.fullmatch(topic) and not is_command_name(topic):
                raise InputError(unknown_command_text(topic, _BUILTIN_NAMES), words[1].start())
            try:
                usage(topic)
            except CommandTextError as error:
                raise InputError(str(error), words[1].start()) from None
            topic = lookup(topic).name
        return ShowHelp(topic)
    if name == "checksum":
        if len(arguments) != 1 or arguments[0] not in ("on", "off"):
            position = words[1].start() if len(words) > 1 else len(line)
            raise InputError("checksum takes on or off", position)
        return SetChecksum(arguments[0] == "on")
    # raw: everything after the word, as typed
    frame = line[words[0].end() :].strip()
    if not frame:
        raise InputError("raw takes a frame to send, e.g. raw #qd!", len(line))
    if not frame.isascii() or " " in frame:
        raise InputError("a raw frame is ASCII without spaces", words[1].start())
    return SendRaw(frame)


def _error_position(line: str, error: CommandTextError) -> int:
    """Where in ``line`` the error is: the offending value, a missing or extra one, the name."""
    stripped = line.strip()
    offset = line.find(stripped)
    words = list(_WORD.finditer(line))
    is_frame = stripped.startswith("#") or (len(words) == 1 and "." in stripped)
    if is_frame:
        if stripped.startswith("#") and not stripped.endswith("!"):
            return len(line.rstrip())
        if error.argument is None:
            return offset
        body = stripped.lstrip("#").rstrip("!")
        body_start = offset + (1 if stripped.startswith("#") else 0)
        return body_start + _value_offset_in_body(body, error.argument)
    try:
        spec = lookup(words[0].group())
    except ValueError:
        return words[0].start()  # an unknown command: point at its name
    names = [argument.name for argument in spec.arguments]
    if error.argument in names:
        return words[1 + names.index(error.argument)].start()
    if len(words) - 1 > len(names):  # too many values: the first extra one
        return words[1 + len(names)].start()
    return len(line.rstrip())  # too few: where the next one goes


def _value_offset_in_body(body: str, argument_name: str) -> int:
    """The offset of an argument's value in a frame body such as ``th.400.25``."""
    segments = body.split(".")
    for count in range(len(segments), 0, -1):  # the longest name first: q.l has a dot
        name = ".".join(segments[:count])
        try:
            spec = lookup(name)
        except ValueError:
            continue
        names = [argument.name for argument in spec.arguments]
        if argument_name not in names:
            return 0
        index = count + names.index(argument_name)
        return sum(len(segment) + 1 for segment in segments[:index])
    return 0
