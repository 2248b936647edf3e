"""``help`` and ``help NAME``: every command with its one-line description, or one in full.

All of it comes from the command table (and the console's own words from
:data:`~rovlink.console.actions.BUILTINS`), so a new command is documented here by itself.
"""

from __future__ import annotations

from rovlink.client import usage
from rovlink.console.actions import BUILTINS
from rovlink.protocol import COMMANDS, lookup

__all__ = ["STOP_KEY_TEXT", "command_help", "overview"]

#: How the stop key is named on screen and in the help.
STOP_KEY_TEXT = "Ctrl-X"

_NAME_WIDTH = max(len(spec.name) for spec in COMMANDS) + 2


def overview() -> list[str]:
    """Every command of the table and every console word, one line each.

    >>> [line for line in overview() if line.strip().startswith("th ")]
    ['  th        horizontal motion: direction (0 ahead, clockwise) and power']
    """
    lines = ["Commands for the robot (type 'help NAME' for one in full):"]
    lines += [f"  {spec.name:<{_NAME_WIDTH}}{spec.description}" for spec in COMMANDS]
    lines.append("Console:")
    lines += [f"  {builtin.name:<{_NAME_WIDTH}}{builtin.description}" for builtin in BUILTINS]
    lines.append(f"  {STOP_KEY_TEXT:<{_NAME_WIDTH}}send #stop! at once, from anywhere in the line")
    lines.append("Type commands as words (th 270 25) or frames (#th.270.25!).")
    return lines


def command_help(name: str) -> list[str]:
    """One command in full: how to type it, its frame, each argument's range, its rules.

    >>> for line in command_help("mvd"): print(line)
    mvd <target_depth_cm 0–9999>
      depth mode: hold this depth, cm from the surface
      frame: #mvd.<target_depth_cm>!
      target_depth_cm: 0–9999, target depth, cm
      motion: dropped by the controller while motors are locked (send start)
      needs depth mode (mvdirect 0)
      protocol rules: P7, P9
    """
    for builtin in BUILTINS:
        if builtin.name == name:
            return [builtin.usage, f"  {builtin.description}"]
    spec = lookup(name)
    lines = [usage(spec.name), f"  {spec.description}", f"  frame: {spec.template()}"]
    for argument in spec.arguments:
        lines.append(
            f"  {argument.name}: {argument.range_text()}"
            + (f", {argument.description}" if argument.description else "")
        )
    if spec.replies:
        replies = ", ".join(f"${reply}" for reply in spec.replies)
        lines.append(f"  replies: {replies}")
    if spec.motion:
        lines.append("  motion: dropped by the controller while motors are locked (send start)")
    if spec.mode is not None:
        lines.append(f"  needs {spec.mode} mode (mvdirect {1 if spec.mode == 'direct' else 0})")
    if spec.aliases:
        lines.append(f"  also spelled: {', '.join(spec.aliases)}")
    lines.append(f"  protocol rules: {', '.join(spec.rules)}")
    return lines
