"""The controller's settings as last sent, to send again after a suspected reset.

A controller that resets (P21) comes back with the defaults of its configuration: its PID gains,
its maximum PWM and its depth calibration, and depth mode (P9). A bridge shows the settings as
last sent — the MAVLink bridge as parameters, both as the vertical mode — so once the controller
answers again after a suspected reset, it sends them again; else a ``RL_MAX_PWM`` of 100 would
quietly be 255 again, and a MANUAL throttle (``#mvs``) dropped in depth mode.
"""

from __future__ import annotations

import asyncio

from rovlink.piloting.tracked import SentFrame, TrackedClient
from rovlink.protocol import Command, Setting, Spec

__all__ = ["KeptSettings", "is_kept"]


def is_kept(spec: Spec) -> bool:
    """Whether a command sets something a reset undoes and sending it again restores: a value
    setting (gains, maximum PWM, depth calibration) or the vertical mode; not motion, the lock,
    queries or the link's own modes.

    >>> from rovlink.protocol import lookup
    >>> [name for name in ("mgmp", "sdk", "mvdirect", "mvs", "start", "qd", "crcon", "slreset")
    ...  if is_kept(lookup(name))]
    ['mgmp', 'sdk', 'mvdirect']
    """
    if spec.motion or spec.replies:
        return False
    if spec.setting is not None:
        return spec.setting is Setting.DIRECT_MODE
    return bool(spec.arguments)


class KeptSettings:
    """Keeps the last frame of each setting sent through ``rov``; :meth:`restore` sends them
    again once, after :meth:`reset_suspected`.

    >>> kept = KeptSettings()
    >>> kept.keep(Command("mgmp", (100,)))
    >>> kept.keep(Command("mvdirect", (1,)))
    >>> kept.keep(Command("mgmp", (120,)))
    >>> [str(command) for command in kept.commands()]
    ['#mvdirect.1!', '#mgmp.120!']
    """

    def __init__(self) -> None:
        self._last: dict[str, Command] = {}
        #: A reset was suspected and the settings have not been sent again since.
        self.pending = False
        self._restoring = asyncio.Lock()

    def follow(self, rov: TrackedClient) -> None:
        """Keep every setting sent through ``rov`` from now on (whoever sends it)."""
        rov.add_sent_listener(self._on_sent)

    def keep(self, command: Command) -> None:
        """A setting was sent: it is the one to send again."""
        if is_kept(command.spec):
            self._last.pop(command.name, None)  # (in the order last sent)
            self._last[command.name] = command

    def commands(self) -> tuple[Command, ...]:
        """The settings as last sent, in the order they were last sent."""
        return tuple(self._last.values())

    def reset_suspected(self) -> None:
        """The controller may have reset: send the settings again when it answers."""
        self.pending = True

    async def restore(self, rov: TrackedClient) -> tuple[Command, ...]:
        """If a reset was suspected, send the settings again (once); the commands sent.

        Concurrent callers wait for one another, so that none goes on (``#start!``) before the
        settings are in.
        """
        async with self._restoring:
            if not self.pending:
                return ()
            self.pending = False
            commands = self.commands()
            try:
                for command in commands:
                    await rov.send(command)
            except BaseException:
                self.pending = True  # (the link went again: all of them, next time)
                raise
            return commands

    async def restore_in_background(self, rov: TrackedClient) -> str | None:
        """:meth:`restore` for a bridge's own task: the frames sent again, as text; ``None``
        if none were due, or if the link went again (they are sent once it is back)."""
        try:
            commands = await self.restore(rov)
        except ConnectionError:
            return None
        return " ".join(str(command) for command in commands) or None

    def _on_sent(self, sent: SentFrame) -> None:
        if sent.command is not None and sent.warning is None:
            self.keep(sent.command)
