"""The command reference in Markdown, generated from the command table (``docs/commands.md``)."""

from __future__ import annotations

from rovlink.protocol.checksum import DEFAULT_ALGORITHM, get_algorithm
from rovlink.protocol.commands import COMMANDS, RESPONSES, Spec
from rovlink.protocol.frames import MAX_FRAME_BYTES

__all__ = ["command_reference_markdown"]


def _example(spec: Spec) -> str:
    # A value from the middle of each range: th gives the seed's own #th.180.50!.
    values = tuple(
        argument.maximum // 2 if argument.signed else (argument.minimum + argument.maximum) // 2
        for argument in spec.arguments
    )
    return spec.kind.start_byte.decode() + spec.body(values) + "!"


def _checksummed(frame: str) -> str:
    body = frame[1:-1].encode()
    return frame[0] + frame[1:-1] + get_algorithm(DEFAULT_ALGORITHM).digits(body).decode() + "!"


def _arguments_text(spec: Spec) -> str:
    if not spec.arguments:
        return "—"
    return "<br>".join(
        f"`{argument.name}` {argument.range_text()}" + (" (signed)" if argument.signed else "")
        for argument in spec.arguments
    )


def _notes(spec: Spec) -> str:
    notes = []
    if spec.exact_match:
        notes.append("exact match, never checksummed")
    if spec.motion:
        notes.append("dropped while locked")
    if spec.mode is not None:
        notes.append(f"{spec.mode.value} mode only")
    if spec.replies:
        notes.append("replies " + ", ".join(f"`${name}`" for name in spec.replies))
    if spec.aliases:
        notes.append("alias " + ", ".join(f"`{alias}`" for alias in spec.aliases))
    if spec.honoured_bare:
        notes.append(f"bare `#{spec.name}!` honoured in checksum mode")
    return "; ".join(notes) or "—"


def _unchecked_frames() -> str:
    """The frames that go without a checksum in checksum mode (P3), in words."""
    frames = [f"`#{spec.name}!`" for spec in COMMANDS if spec.exact_match]
    frames += [f"the bare `#{spec.name}!`" for spec in COMMANDS if spec.honoured_bare]
    return ", ".join(frames[:-1]) + " and " + frames[-1]


def _table(specs: tuple[Spec, ...]) -> list[str]:
    lines = [
        "| name | frame | arguments | description | example | with CRC-8 | notes | rules |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for spec in specs:
        example = _example(spec)
        checksummed = example if spec.exact_match else _checksummed(example)
        lines.append(
            f"| `{spec.name}` | `{spec.template()}` | {_arguments_text(spec)} | "
            f"{spec.description} | `{example}` | `{checksummed}` | {_notes(spec)} | "
            f"{', '.join(spec.rules)} |"
        )
    return lines


def command_reference_markdown() -> str:
    """The whole command reference page.

    >>> "| `th` |" in command_reference_markdown()
    True
    """
    lines = [
        "# Command reference",
        "",
        "Generated from the command table in `rovlink.protocol.commands` by",
        "`rovlink reference > docs/commands.md`; a test keeps this page current.",
        "The rules (P1, P2, …) are the decisions of the protocol specification, "
        "[PROTOCOL.md](../PROTOCOL.md) Part 2.",
        "",
        f"A command is `#` BODY [checksum] `!`, a response `$` BODY [checksum] `!`; a frame is at "
        f"most {MAX_FRAME_BYTES} bytes. Values are decimal integers; signed values are written "
        f"with a sign (`+0` for zero). In checksum mode every frame but {_unchecked_frames()} "
        "carries two hex digits of the checksum of its body before the `!`.",
        "",
        f"## Commands (host → controller), {len(COMMANDS)}",
        "",
        *_table(COMMANDS),
        "",
        f"## Responses (controller → host), {len(RESPONSES)}",
        "",
        *_table(RESPONSES),
        "",
    ]
    return "\n".join(lines)
