"""Completion and argument hints for the console's input line, from the command table.

Pure functions of the text before the cursor; the prompt_toolkit completer and toolbar in
:mod:`rovlink.console.app` only translate what they return.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from rovlink.client.command_text import complete_names
from rovlink.console.actions import BUILTINS
from rovlink.protocol import Spec, UnknownCommandError, lookup

__all__ = ["Hint", "Suggestion", "argument_hint", "suggestions"]

_WORD = re.compile(r"[^\s,]+")
_BUILTIN_BY_NAME = {builtin.name: builtin for builtin in BUILTINS}
#: ``exit`` is ``quit``'s other name: completed and hinted as it (it had neither).
_BUILTIN_BY_NAME["exit"] = _BUILTIN_BY_NAME["quit"]
_CHECKSUM_WORDS = (("on", "checksum on every frame (#crcon!)"), ("off", "no checksums (#crcoff!)"))


@dataclass(frozen=True, slots=True)
class Suggestion:
    """One completion: ``text`` replaces the ``-start`` characters before the cursor."""

    text: str
    start: int
    display: str
    meta: str


@dataclass(frozen=True, slots=True)
class Hint:
    """How to type the command being typed; ``current`` is the argument the cursor is on."""

    name: str
    description: str
    arguments: tuple[str, ...]
    current: int | None

    def text(self) -> str:
        """The hint in one line, the current argument in brackets.

        >>> argument_hint("th 270 ").text()
        'th <direction_deg 0–360> [<power_percent 0–100>]: horizontal power, %'
        """
        parts = [
            f"[{part}]" if index == self.current else part
            for index, part in enumerate(self.arguments)
        ]
        detail = self.description
        return " ".join([self.name, *parts]) + (f": {detail}" if detail else "")


def _name_suggestions(prefix: str, *, frame: bool = False) -> list[Suggestion]:
    found = []
    for name in complete_names(prefix):
        spec = lookup(name)
        text = name
        if frame:
            text = f"#{name}." if spec.arguments else f"#{name}!"
        found.append(Suggestion(text, -(len(prefix) + frame), text, spec.description))
    if not frame:
        found += [
            Suggestion(name, -len(prefix), name, builtin.description)
            for name, builtin in _BUILTIN_BY_NAME.items()
            if name.startswith(prefix) and (name != "exit" or prefix.startswith("e"))
        ]
    return found


def suggestions(before_cursor: str) -> list[Suggestion]:
    """What may come at the cursor: command names, ``on``/``off``, argument values or hints.

    >>> [s.text for s in suggestions("mvp")]
    ['mvpdp', 'mvpdi', 'mvpidd']
    >>> [s.text for s in suggestions("#q.")]
    ['#q.l!']
    >>> [s.display for s in suggestions("th 270 ")]
    ['<power_percent 0–100>']
    """
    words = _WORD.findall(before_cursor)
    typing_word = (
        bool(before_cursor) and not before_cursor[-1].isspace() and before_cursor[-1] != ","
    )
    partial = words[-1] if typing_word else ""
    done = words[:-1] if typing_word else words
    if not done:
        if partial.startswith("#"):
            return (
                _name_suggestions(partial[1:], frame=True)
                if "." not in partial[1:] or partial[1:].startswith("q.")
                else []
            )
        return _name_suggestions(partial)
    first = done[0]
    if first == "help" and len(done) == 1:
        return _name_suggestions(partial)
    if first == "checksum" and len(done) == 1:
        return [
            Suggestion(word, -len(partial), word, meta)
            for word, meta in _CHECKSUM_WORDS
            if word.startswith(partial)
        ]
    spec = _spec(first)
    if spec is None:
        return []
    index = len(done) - 1
    if index >= len(spec.arguments):
        return []
    argument = spec.arguments[index]
    if (argument.minimum, argument.maximum) == (0, 1):
        return [
            Suggestion(value, -len(partial), value, argument.description)
            for value in ("0", "1")
            if value.startswith(partial)
        ]
    hint = f"<{argument.name} {argument.range_text()}>"
    return [Suggestion("", 0, hint, argument.description)]


def _spec(name: str) -> Spec | None:
    try:
        return lookup(name)
    except UnknownCommandError:
        return None


def _frame_hint(body: str) -> tuple[Spec, int] | None:
    segments = body.split(".")
    for count in range(len(segments), 0, -1):  # the longest name first: q.l has a dot
        spec = _spec(".".join(segments[:count]))
        if spec is not None:
            return spec, len(segments) - count - 1
    return None


def argument_hint(before_cursor: str) -> Hint | None:
    """How to type the command at the start of the line, and which argument is being typed.

    >>> argument_hint("mvs -").current
    0
    >>> argument_hint("#th.90.").text()
    'th <direction_deg 0–360> [<power_percent 0–100>]: horizontal power, %'
    """
    stripped = before_cursor.lstrip()
    if not stripped:
        return None
    if stripped.startswith("#"):
        found = _frame_hint(stripped[1:].rstrip("!"))
        if found is None:
            return None
        spec, current_index = found
    else:
        words = _WORD.findall(stripped)
        builtin = _BUILTIN_BY_NAME.get(words[0])
        if builtin is not None:
            return Hint(builtin.usage, builtin.description, (), None)
        spec_or_none = _spec(words[0])
        if spec_or_none is None:
            return None
        spec = spec_or_none
        typing_word = not stripped[-1].isspace() and stripped[-1] != ","
        current_index = len(words) - 1 - (1 if typing_word else 0)
    arguments = tuple(f"<{argument.name} {argument.range_text()}>" for argument in spec.arguments)
    current = current_index if 0 <= current_index < len(arguments) else None
    description = spec.arguments[current].description if current is not None else spec.description
    return Hint(spec.name, description, arguments, current)
