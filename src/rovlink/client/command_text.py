"""Command text as people type it — ``th 270 25``, ``mvs -50``, ``qd``, ``#qd!`` — to a Command.

The one place that reads command text: ``rovlink send`` uses it for its arguments and the
console for its input line, completion and help. Everything about names, argument counts and
ranges comes from the command table; errors name the command, the argument and its range.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable

from rovlink.protocol import (
    COMMANDS,
    Command,
    FrameError,
    Kind,
    Spec,
    UnknownCommandError,
    lookup,
    parse_body,
)
from rovlink.protocol.commands import SPELLINGS

__all__ = [
    "CommandTextError",
    "complete_names",
    "is_command_name",
    "parse_command_text",
    "unknown_command_text",
    "usage",
]

_SEPARATORS = re.compile(r"[\s,]+")
# ASCII digits only (``\d`` would take "٣" for 3), and a "+" only where the argument is signed,
# as in a frame (P6); "-" is let through to the range check, which names the range.
_INTEGER = re.compile(r"-?[0-9]+")
_SIGNED_INTEGER = re.compile(r"[+-]?[0-9]+")


class CommandTextError(ValueError):
    """Command text that is not a valid command; ``argument`` names the culprit, if one is.

    >>> str(CommandTextError("th: power_percent must be in 0–100, got 150", "power_percent"))
    'th: power_percent must be in 0–100, got 150'
    """

    def __init__(self, message: str, argument: str | None = None) -> None:
        super().__init__(message)
        self.argument = argument


def usage(name: str) -> str:
    """How to type a command, with each argument's range.

    >>> usage("th")
    'th <direction_deg 0–360> <power_percent 0–100>'
    >>> usage("mvs")
    'mvs <thrust_percent -100…+100>'
    """
    spec = _spec(name)
    parts = [
        spec.name,
        *(f"<{argument.name} {argument.range_text()}>" for argument in spec.arguments),
    ]
    return " ".join(parts)


def complete_names(prefix: str) -> list[str]:
    """Command names (aliases excluded) that start with ``prefix``, in table order.

    >>> complete_names("mvp")
    ['mvpdp', 'mvpdi', 'mvpidd']
    """
    return [spec.name for spec in COMMANDS if spec.name.startswith(prefix)]


def is_command_name(word: str) -> bool:
    """Whether ``word`` names a command of the table, as typed (an alias too).

    >>> is_command_name("q.l"), is_command_name("TH"), is_command_name("th.90.30")
    (True, False, False)
    """
    return word in SPELLINGS[Kind.COMMAND]


def unknown_command_text(name: str, other_names: Iterable[str] = ()) -> str:
    """What to say of ``name``, which names no command: with the names it may have been
    meant for, among the table's and ``other_names`` (the words of a tool's own, such as the
    console's ``status``, that a typo of would otherwise be taken for a command's).

    >>> unknown_command_text("stauts", ["status"])
    "unknown command 'stauts'; did you mean status, start?"
    >>> unknown_command_text("Quit", ["quit"])
    "unknown command 'Quit': commands are lower-case, did you mean quit?"
    """
    spellings = [*SPELLINGS[Kind.COMMAND], *other_names]
    typed = name.lower()  # (caps lock: a name in capitals is matched as it would be)
    if typed in spellings:  # (P6: commands are lower-case and case-sensitive)
        return f"unknown command {name!r}: commands are lower-case, did you mean {typed}?"
    close = difflib.get_close_matches(typed, spellings, n=3, cutoff=0.6)
    # A word that starts with a command's name ("thrust" for "th") is probably that command.
    close += [s for s in spellings if len(s) > 1 and typed.startswith(s) and s not in close]
    hint = f"; did you mean {', '.join(close)}?" if close else ""
    return f"unknown command {name!r}{hint}"


def _spec(name: str) -> Spec:
    try:
        return lookup(name)
    except UnknownCommandError:
        raise CommandTextError(unknown_command_text(name)) from None


def _from_body(body: str, text: str) -> Command:
    if not body:
        raise CommandTextError(f"empty frame {text!r}")
    try:
        message = parse_body(Kind.COMMAND, body)
    except FrameError as error:
        name = body.split(".", 1)[0]
        if error.detail.startswith("unknown"):
            _spec(name)  # raises with suggestions
        raise CommandTextError(error.detail, _argument_in(error.detail)) from None
    return Command(message.name, message.values)


def _argument_in(detail: str) -> str | None:
    match = re.match(r"[\w.+-]+: (\w+) ", detail)
    return match.group(1) if match else None


def _from_words(words: list[str]) -> Command:
    spec = _spec(words[0])
    tokens = words[1:]
    if len(tokens) != len(spec.arguments):
        expected = usage(spec.name)
        raise CommandTextError(
            f"{spec.name} takes {len(spec.arguments)} value(s), got {len(tokens)}: {expected}"
        )
    values = []
    for token, argument in zip(tokens, spec.arguments, strict=True):
        range_text = argument.range_text()
        if not (_SIGNED_INTEGER if argument.signed else _INTEGER).fullmatch(token):
            raise CommandTextError(
                f"{spec.name}: {argument.name} must be an integer in {range_text}, got {token!r}",
                argument.name,
            )
        value = int(token)
        if not argument.minimum <= value <= argument.maximum:
            raise CommandTextError(
                f"{spec.name}: {argument.name} must be in {range_text}, got {token}",
                argument.name,
            )
        values.append(value)
    return Command(spec.name, tuple(values))


def parse_command_text(text: str) -> Command:
    """The command in ``text``: words (``th 270 25``), a body (``th.270.25``) or a frame.

    >>> str(parse_command_text("th 270 25"))
    '#th.270.25!'
    >>> str(parse_command_text("mvs -50"))
    '#mvs.-50!'
    >>> parse_command_text("#q.l!").name
    'q.l'
    >>> try:
    ...     parse_command_text("th 400 25")
    ... except ValueError as error:
    ...     print(error)
    th: direction_deg must be in 0–360, got 400
    """
    if not isinstance(text, str):  # (bytes would fail deep inside, naming no argument)
        raise TypeError(f"parse_command_text: text must be a str, got {text!r}")
    stripped = text.strip()
    if not stripped:
        raise CommandTextError("empty command")
    if stripped.startswith("#"):
        if not stripped.endswith("!") or len(stripped) < 2:
            raise CommandTextError(f"a frame must end with '!': {stripped!r}")
        if "#" in stripped[1:] or "!" in stripped[:-1]:
            raise CommandTextError(f"one frame at a time: {stripped!r} holds more than one")
        return _from_body(stripped[1:-1], stripped)
    words = [word for word in _SEPARATORS.split(stripped) if word]
    if len(words) == 1 and "." in words[0] and words[0] not in SPELLINGS[Kind.COMMAND]:
        return _from_body(words[0], stripped)
    return _from_words(words)
