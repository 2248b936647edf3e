"""The command topic's rules: which commands a broker may send, and what they become."""

from __future__ import annotations

from rovlink.client.command_text import parse_command_text
from rovlink.protocol import Command, Setting

__all__ = ["CommandPolicy", "CommandRefusedError"]

_LINK_SETTINGS = (Setting.CHECKSUM, Setting.DEBUG)


class CommandRefusedError(ValueError):
    """A command the bridge will not send; the message says why."""


class CommandPolicy:
    """``stop`` is always accepted; everything else only with ``allow_commands``.

    The checksum and debug modes belong to the bridge's own link, so they are refused.

    >>> str(CommandPolicy(allow_commands=False).check("stop"))
    '#stop!'
    >>> try:
    ...     CommandPolicy(allow_commands=False).check("start")
    ... except CommandRefusedError as error:
    ...     print(error)
    commands are refused: the bridge runs without --allow-commands (stop is always accepted)
    """

    def __init__(self, *, allow_commands: bool) -> None:
        self.allow_commands = allow_commands

    def check(self, text: str) -> Command:
        """The command in ``text`` if it may be sent (``ValueError`` naming the problem)."""
        command = parse_command_text(text)  # CommandTextError (a ValueError) names the argument
        if command.name == "stop":
            return command
        if not self.allow_commands:
            raise CommandRefusedError(
                "commands are refused: the bridge runs without --allow-commands "
                "(stop is always accepted)"
            )
        setting = command.setting
        if setting is not None and setting[0] in _LINK_SETTINGS:
            raise CommandRefusedError(
                f"{command.name}: the bridge's link owns the checksum and debug modes"
            )
        return command
