"""The command table in C, for the reference firmware (``firmware/c/rovlink_commands.{h,c}``).

The C reference takes every name, argument range and flag from these generated files, so the
command table stays the one place a fact about a command lives. Regenerate after changing it::

    python -m rovlink.protocol.c_table firmware/c

A test fails while the files in the repository are stale.
"""

from __future__ import annotations

import sys
from pathlib import Path

from rovlink.protocol.commands import COMMANDS, RESPONSES, Argument, Setting, Spec, VerticalMode
from rovlink.protocol.frames import MAX_FRAME_BYTES

__all__ = ["HEADER_NAME", "SOURCE_NAME", "identifier", "render_header", "render_source"]

HEADER_NAME = "rovlink_commands.h"
SOURCE_NAME = "rovlink_commands.c"

_NOTICE = (
    "/* Generated from src/rovlink/protocol/commands.py by\n"
    " *     python -m rovlink.protocol.c_table firmware/c\n"
    " * Do not edit: change the command table and regenerate. */\n"
)
#: What the C table's int16_t range fields hold; the C parser (parse_number in rovlink_proto.c)
#: stops counting a number past 99 999, so that it never overflows, which is beyond these too.
_C_RANGE = (-(2**15), 2**15 - 1)


def identifier(spec: Spec) -> str:
    """The C name of a command or reply, e.g. ``RL_CMD_Q_L``, ``RL_CMD_H_OPEN``."""
    name = spec.name.replace(".", "_").replace("+", "_OPEN").replace("-", "_CLOSE").upper()
    prefix = "RL_CMD_" if spec in COMMANDS else "RL_REPLY_"
    return prefix + name


def _flags(spec: Spec) -> str:
    flags = []
    if spec.exact_match:
        flags.append("RL_EXACT_MATCH")
    if spec.honoured_bare:
        flags.append("RL_HONOURED_BARE")
    if spec.motion:
        flags.append("RL_MOTION")
    if spec.mode is VerticalMode.DIRECT:
        flags.append("RL_NEEDS_DIRECT")
    if spec.mode is VerticalMode.DEPTH:
        flags.append("RL_NEEDS_DEPTH")
    return " | ".join(flags) or "0"


def _setting(spec: Spec) -> str:
    if spec.setting is None:
        return "RL_SETTING_NONE, 0"
    value = "RL_FROM_ARGUMENT" if spec.setting_value is None else str(int(spec.setting_value))
    return f"RL_SETTING_{spec.setting.name}, {value}"


def _c_argument(spec: Spec, argument: Argument) -> str:
    """An argument as the C table's rl_argument; an error for a range it cannot hold."""
    low, high = _C_RANGE
    if not low <= argument.minimum <= argument.maximum <= high:
        raise ValueError(
            f"{spec.name}: the range {argument.minimum}..{argument.maximum} of {argument.name}"
            f" does not fit the C table's 16-bit range fields ({low}..{high})"
        )
    return f"{{{argument.minimum}, {argument.maximum}, {int(argument.signed)}}}"


def _arguments(spec: Spec) -> str:
    items = [_c_argument(spec, argument) for argument in spec.arguments]
    return "{" + ", ".join(items or ["{0, 0, 0}"]) + "}"


def _replies(spec: Spec) -> str:
    by_name = {reply.name: reply for reply in RESPONSES}
    items = [identifier(by_name[name]) for name in spec.replies]
    return "{" + ", ".join(items or ["0"]) + "}"


def _name_bytes() -> int:
    """The C tables' name field: the longest spelling of a command or a reply and its NUL (C
    takes a string that fills the field without one, and strlen then reads past it)."""
    return 1 + max(
        len(spelling) for spec in (*COMMANDS, *RESPONSES) for spelling in (spec.name, *spec.aliases)
    )


def render_header() -> str:
    """``rovlink_commands.h``: the ids, the table's types and its declarations."""
    max_arguments = max(len(spec.arguments) for spec in COMMANDS)
    max_replies = max(len(spec.replies) for spec in COMMANDS)
    commands = ",\n".join(f"    {identifier(spec)}" for spec in COMMANDS)
    replies = ",\n".join(f"    {identifier(spec)}" for spec in RESPONSES)
    spellings = sum(1 + len(spec.aliases) for spec in COMMANDS)
    settings = ",\n".join(f"    RL_SETTING_{setting.name}" for setting in Setting)
    return f"""{_NOTICE}
#ifndef ROVLINK_COMMANDS_H
#define ROVLINK_COMMANDS_H

#include <stdint.h>

/* The longest whole frame, start and end characters included (P1). */
#define RL_MAX_FRAME_BYTES {MAX_FRAME_BYTES}
#define RL_MAX_ARGUMENTS {max_arguments}
#define RL_MAX_REPLIES {max_replies}
#define RL_NAME_BYTES {_name_bytes()}
#define RL_SPELLING_COUNT {spellings}

/* Flags of a command (P3, P7, P9). */
#define RL_EXACT_MATCH 0x01u   /* taken by exact match, never with a checksum */
#define RL_HONOURED_BARE 0x02u /* taken without a checksum even in checksum mode */
#define RL_MOTION 0x04u        /* dropped while the motors are locked */
#define RL_NEEDS_DIRECT 0x08u  /* dropped unless in direct mode */
#define RL_NEEDS_DEPTH 0x10u   /* dropped unless in depth mode */

typedef enum {{
{commands},
    RL_CMD_COUNT
}} rl_command_id;

typedef enum {{
{replies},
    RL_REPLY_COUNT
}} rl_reply_id;

typedef struct {{
    int16_t minimum;
    int16_t maximum;
    uint8_t is_signed;
}} rl_argument;

/* The on/off state a command switches, and to what (P3, P5, P7, P9, P16). */
typedef enum {{
    RL_SETTING_NONE,
{settings}
}} rl_setting;
#define RL_FROM_ARGUMENT 2u /* the setting takes the command's 0/1 argument */

typedef struct {{
    uint8_t flags;
    uint8_t setting;
    uint8_t setting_value;
    uint8_t argument_count;
    rl_argument arguments[RL_MAX_ARGUMENTS];
    uint8_t reply_count;
    uint8_t replies[RL_MAX_REPLIES];
}} rl_command_spec;

typedef struct {{
    char name[RL_NAME_BYTES];
    uint8_t command;
}} rl_spelling;

typedef struct {{
    char name[RL_NAME_BYTES];
    rl_argument argument;
}} rl_reply_spec;

/* On AVR the tables live in flash (PROGMEM): read them with memcpy_P, as rovlink_proto.c does. */
#if defined(__AVR__)
#include <avr/pgmspace.h>
#define RL_ROM PROGMEM
#else
#define RL_ROM
#endif

extern const rl_command_spec rl_command_specs[RL_CMD_COUNT] RL_ROM;
extern const rl_spelling rl_spellings[RL_SPELLING_COUNT] RL_ROM;
extern const rl_reply_spec rl_reply_specs[RL_REPLY_COUNT] RL_ROM;

#endif /* ROVLINK_COMMANDS_H */
"""


def render_source() -> str:
    """``rovlink_commands.c``: the tables."""
    specs = ",\n".join(
        f"    /* {spec.name} */ {{{_flags(spec)}, {_setting(spec)}, {len(spec.arguments)}, "
        f"{_arguments(spec)}, "
        f"{len(spec.replies)}, {_replies(spec)}}}"
        for spec in COMMANDS
    )
    spellings = ",\n".join(
        f'    {{"{spelling}", {identifier(spec)}}}'
        for spec in COMMANDS
        for spelling in (spec.name, *spec.aliases)
    )
    replies = ",\n".join(
        f'    {{"{spec.name}", {_c_argument(spec, spec.arguments[0])}}}' for spec in RESPONSES
    )
    return f"""{_NOTICE}
#include "{HEADER_NAME}"

const rl_command_spec rl_command_specs[RL_CMD_COUNT] RL_ROM = {{
{specs}
}};

const rl_spelling rl_spellings[RL_SPELLING_COUNT] RL_ROM = {{
{spellings}
}};

const rl_reply_spec rl_reply_specs[RL_REPLY_COUNT] RL_ROM = {{
{replies}
}};
"""


def main(argv: list[str]) -> int:
    """Write both files into the directory ``argv[0]``."""
    if len(argv) != 1:
        print("usage: python -m rovlink.protocol.c_table DIRECTORY", file=sys.stderr)
        return 2
    directory = Path(argv[0])
    (directory / HEADER_NAME).write_text(render_header(), encoding="ascii")
    (directory / SOURCE_NAME).write_text(render_source(), encoding="ascii")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
