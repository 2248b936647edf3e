"""The pilot's stick to motion frames, with a dead-man and a watchdog that fails safe.

The page sends the pilot's input (dead-man, direction, power, vertical) whenever it changes and,
while the dead-man is held, at a steady rate. The relay turns it into ``th``, ``mvs`` and
``mvd`` frames, and its watchdog — run by the server every few tens of milliseconds, whatever
the page does — zeroes the thrust when the input stops arriving, when the gamepad stops
reporting, when the dead-man is let go, or when the pilot leaves. After such a cut the dead-man
must be released and pressed again before anything moves: a pad that wakes up with the button
still reading "held" does not drive the robot off on its own.

What was last sent is the :class:`~rovlink.piloting.CommandedState` the tracked client keeps
from the driver's own record of the bytes it wrote, so a ``#start!`` or ``#stop!`` (which clear
the set-points on the controller) is seen here too, and only a change goes on the wire.
Sans-I/O: the caller passes the time and sends the commands returned.
"""

from __future__ import annotations

from dataclasses import dataclass

from rovlink.piloting import CommandedState, LockState
from rovlink.protocol import Command, VerticalMode, lookup

__all__ = [
    "DEPTH_NUDGE_CM_PER_S",
    "LOCKED_STATUS",
    "MIN_MOTION_INTERVAL_S",
    "RENEW_S",
    "STALE_INPUT_S",
    "UNKNOWN_LOCK_STATUS",
    "PilotInput",
    "ThrustRelay",
    "is_zero_thrust",
]

#: Input older than this is stale: no message from the page, or a gamepad that stopped
#: reporting (P23: 300 ms for a gamepad or a browser).
STALE_INPUT_S = 0.3
#: A non-zero motion is sent again this often while the input is fresh: the driver's own
#: ``motion_timeout`` (a second line of defence) expires a motion that was not renewed.
RENEW_S = 0.5
#: Non-zero motion frames go out at most this often (a stick that moves all the time would
#: otherwise send one per poll of the page, more than a slow serial line carries); the latest
#: input wins. Zero thrust is never held back.
MIN_MOTION_INTERVAL_S = 0.02
#: How fast a full deflection of the vertical stick moves the depth target in depth mode.
DEPTH_NUDGE_CM_PER_S = 30.0
#: The relay's status while locked as last sent: armed or not, nothing moves until ``#start!``.
LOCKED_STATUS = "motors locked: unlock (#start!) to fly"
#: Flying while the lock is not known (nothing sent yet, or the link was reopened): the frames
#: go out, and a controller that is locked drops them.
UNKNOWN_LOCK_STATUS = (
    "flying, if the motors are unlocked (the lock is not known: unlock with #start!)"
)
#: Longest interval a nudge integrates over (a late message does not jump the target).
_MAX_NUDGE_STEP_S = 0.1

_TH = lookup("th")
_MVS = lookup("mvs")
_MVD = lookup("mvd")
_DIRECTION = _TH.arguments[0]
_POWER = _TH.arguments[1]
_THRUST = _MVS.arguments[0]
_TARGET = _MVD.arguments[0]


@dataclass(frozen=True, slots=True)
class PilotInput:
    """One reading of the pilot's controls, as the page sends it.

    ``pad_timestamp_ms`` is the gamepad's own ``timestamp`` (it advances whenever the pad
    reports); ``None`` for the keyboard.
    """

    deadman: bool
    direction_deg: int = 0
    power_percent: int = 0
    vertical_percent: int = 0
    pad_timestamp_ms: float | None = None

    def __post_init__(self) -> None:
        for name, argument in (
            ("direction_deg", _DIRECTION),
            ("power_percent", _POWER),
            ("vertical_percent", _THRUST),
        ):
            value = getattr(self, name)
            if not argument.check(value):
                raise ValueError(f"{name} must be in {argument.range_text()}, got {value}")


class ThrustRelay:
    """Turns pilot input into motion frames and cuts them when the input is not trustworthy.

    >>> state = CommandedState()
    >>> relay = ThrustRelay(state)
    >>> relay.update(PilotInput(deadman=True, direction_deg=90, power_percent=40), now_s=0.0)
    []
    >>> relay.status   # the dead-man must be seen released first
    'release the dead-man to arm'
    >>> relay.update(PilotInput(deadman=False), now_s=0.05)
    []
    >>> [str(c) for c in relay.update(PilotInput(True, 90, 40), now_s=0.1)]
    ['#th.90.40!']
    """

    def __init__(
        self,
        commanded: CommandedState,
        *,
        stale_input_s: float = STALE_INPUT_S,
        renew_s: float = RENEW_S,
        min_interval_s: float = MIN_MOTION_INTERVAL_S,
        depth_nudge_cm_per_s: float = DEPTH_NUDGE_CM_PER_S,
    ) -> None:
        self.commanded = commanded
        self.stale_input_s = stale_input_s
        self.renew_s = renew_s
        self.min_interval_s = min_interval_s
        self.depth_nudge_cm_per_s = depth_nudge_cm_per_s
        #: The dead-man was seen released since the last cut: pressing it may move the robot.
        self.armed = False
        #: Why the last cut happened, for the pilot's screen; ``None`` while flying normally.
        self.cut_reason: str | None = "no input yet"
        self._last_input: PilotInput | None = None
        self._input_at_s: float | None = None
        self._pad_advanced_at_s: float | None = None
        self._motion_sent_at_s: float | None = None
        self._nudge_at_s: float | None = None
        self._target_cm: float | None = None
        #: An input whose thrust was held back by ``min_interval_s``, for :meth:`flush`.
        self._pending: PilotInput | None = None

    # -- what the page sends -------------------------------------------------------------------

    def update(
        self, pilot: PilotInput, now_s: float, *, depth_cm: int | None = None
    ) -> list[Command]:
        """The pilot's latest input; returns the frames to send (often none).

        ``depth_cm`` is the latest depth reading: the first nudge in depth mode starts from it
        when no target was sent.
        """
        previous = self._last_input
        self._last_input = pilot
        self._input_at_s = now_s
        if pilot.pad_timestamp_ms is None or (
            previous is None or previous.pad_timestamp_ms != pilot.pad_timestamp_ms
        ):
            self._pad_advanced_at_s = now_s
        if not pilot.deadman:
            self._nudge_at_s = None
            self._target_cm = None
            self._pending = None
            self.armed = True
            self.cut_reason = None
            return self._zero_commands()
        if not self.armed:
            return []
        stale = self._stale_because(now_s)
        if stale is not None:
            return self.cut(stale)
        self.cut_reason = None
        return self._motion_commands(pilot, now_s, depth_cm)

    def check(self, now_s: float) -> list[Command]:
        """The watchdog, called by the server every few tens of milliseconds: zero thrust when
        the pilot's input went stale while the dead-man was held (else what :meth:`flush`
        has due)."""
        pilot = self._last_input
        if pilot is None or not pilot.deadman or not self.armed:
            return []
        stale = self._stale_because(now_s)
        return self.cut(stale) if stale is not None else self.flush(now_s)

    @property
    def due_s(self) -> float | None:
        """When an input held back by ``min_interval_s`` may go out; ``None``: nothing held."""
        if self._pending is None or self._motion_sent_at_s is None:
            return None
        return self._motion_sent_at_s + self.min_interval_s

    def flush(self, now_s: float) -> list[Command]:
        """The thrust of the input held back by ``min_interval_s``, once it is due."""
        pilot = self._pending
        due_s = self.due_s
        if pilot is None or due_s is None or now_s < due_s:
            return []
        if not self.armed or self._stale_because(now_s) is not None:
            self._pending = None
            return []  # the watchdog's business
        if self.commanded.lock is LockState.LOCKED:
            self._pending = None
            return []
        return self._thrust_commands(pilot, now_s)

    def cut(self, reason: str) -> list[Command]:
        """Stop relaying (the pilot left, hid the page, lost control, pressed STOP...): the zero
        thrust frames to send; the dead-man must be released and pressed again.

        They are returned while locked as last sent too: harmless if the controller drops
        them, and they cover a lock the controller never got.
        """
        self.armed = False
        self.cut_reason = reason
        self._nudge_at_s = None
        self._target_cm = None
        self._pending = None
        return self._zero_commands(always=True)

    def disarm(self) -> None:
        """A new pilot: nothing moves until their dead-man is seen released, then pressed."""
        self.armed = False
        self.cut_reason = "no input yet"
        self._last_input = None
        self._pending = None
        self._nudge_at_s = None
        self._target_cm = None

    @property
    def moving(self) -> bool:
        """Whether a non-zero thrust is commanded (as last sent)."""
        commanded = self.commanded
        return commanded.power_percent > 0 or (
            commanded.vertical_mode is VerticalMode.DIRECT
            and commanded.vertical_thrust_percent != 0
        )

    @property
    def status(self) -> str:
        """The relay's state in words: ``flying``, ``armed``, or why nothing moves.

        Locked as last sent (after STOP), nothing is relayed however the stick is held, and
        the status says so rather than ``flying``:

        >>> state = CommandedState()
        >>> relay = ThrustRelay(state)
        >>> state.apply(Command("stop"))
        >>> _ = relay.update(PilotInput(deadman=False), now_s=0.0)
        >>> relay.update(PilotInput(True, 90, 40), now_s=0.05), relay.status
        ([], 'motors locked: unlock (#start!) to fly')
        """
        if not self.armed:
            return (
                "release the dead-man to arm"
                if self.cut_reason in (None, "no input yet")
                else f"cut: {self.cut_reason}; release the dead-man to arm"
            )
        lock = self.commanded.lock
        if lock is LockState.LOCKED:
            return LOCKED_STATUS
        pilot = self._last_input
        if pilot is None or not pilot.deadman:
            return "armed (dead-man released)"
        return "flying" if lock is LockState.UNLOCKED else UNKNOWN_LOCK_STATUS

    # -- internals ------------------------------------------------------------------------------

    def _stale_because(self, now_s: float) -> str | None:
        if self._input_at_s is not None and now_s - self._input_at_s > self.stale_input_s:
            return f"no input from the page for {self.stale_input_s * 1000:.0f} ms"
        if (
            self._pad_advanced_at_s is not None
            and now_s - self._pad_advanced_at_s > self.stale_input_s
        ):
            return f"the gamepad reported nothing for {self.stale_input_s * 1000:.0f} ms"
        return None

    def _zero_commands(self, *, always: bool = False) -> list[Command]:
        """Zero horizontal power (keeping the direction) and, in direct mode, zero vertical
        thrust; with ``always``, also when the state as last sent says it is already zero.

        The mode is the one as last sent. With no mode sent yet, a cut (``always``) zeroes the
        vertical thrust too: the controller may be in direct mode, left there by another
        program, and in depth mode it drops ``mvs`` while its PID holds the depth (P9).
        """
        commanded = self.commanded
        commands: list[Command] = []
        if always or commanded.power_percent > 0:
            commands.append(Command("th", (commanded.direction_deg, 0)))
        direct = commanded.vertical_mode is VerticalMode.DIRECT
        if (always and commanded.vertical_mode is not VerticalMode.DEPTH) or (
            direct and commanded.vertical_thrust_percent != 0
        ):
            commands.append(Command("mvs", (0,)))
        self._motion_sent_at_s = None
        return commands

    def _motion_commands(
        self, pilot: PilotInput, now_s: float, depth_cm: int | None
    ) -> list[Command]:
        if self.commanded.lock is LockState.LOCKED:
            self._pending = None
            return []  # the controller would drop them (P7): nothing to relay until start
        commands = self._thrust_commands(pilot, now_s)
        if self.commanded.vertical_mode is not VerticalMode.DIRECT:
            nudge = self._nudge(pilot, now_s, depth_cm)
            if nudge is not None:
                commands.append(nudge)
        return commands

    def _thrust_commands(self, pilot: PilotInput, now_s: float) -> list[Command]:
        """``th`` and ``mvs`` for the pilot's input. A change to zero goes at once; any other
        change at most every ``min_interval_s``, the latest input winning (held in
        :attr:`_pending` until :meth:`flush`)."""
        commanded = self.commanded
        renew = (
            self.moving
            and self._motion_sent_at_s is not None
            and now_s - self._motion_sent_at_s >= self.renew_s
        )
        commands: list[Command] = []
        if pilot.power_percent > 0:
            direction_deg = pilot.direction_deg % 360  # (360 ≡ 0, P11: the same heading)
            if renew or (direction_deg, pilot.power_percent) != (
                commanded.direction_deg,
                commanded.power_percent,
            ):
                commands.append(Command("th", (direction_deg, pilot.power_percent)))
        elif commanded.power_percent > 0:
            commands.append(Command("th", (commanded.direction_deg, 0)))
        if commanded.vertical_mode is VerticalMode.DIRECT and (
            pilot.vertical_percent != commanded.vertical_thrust_percent
            or (renew and pilot.vertical_percent != 0)
        ):
            commands.append(Command("mvs", (pilot.vertical_percent,)))
        zeroes = [command for command in commands if is_zero_thrust(command)]
        sent_at_s = self._motion_sent_at_s
        if (
            len(zeroes) < len(commands)
            and sent_at_s is not None
            and now_s - sent_at_s < self.min_interval_s
        ):
            self._pending = pilot
            return zeroes
        self._pending = None
        if len(zeroes) < len(commands):
            self._motion_sent_at_s = now_s
        return commands

    def _nudge(self, pilot: PilotInput, now_s: float, depth_cm: int | None) -> Command | None:
        """Depth mode: the vertical stick moves the depth target (up is shallower)."""
        last_s, self._nudge_at_s = self._nudge_at_s, now_s
        if pilot.vertical_percent == 0 or last_s is None:
            self._target_cm = None
            return None
        if self._target_cm is None:
            base = self.commanded.target_depth_cm
            if base is None:
                base = depth_cm
            if base is None:
                return None  # no target sent and no depth read yet: nothing to nudge from
            self._target_cm = float(base)
        step_s = min(now_s - last_s, _MAX_NUDGE_STEP_S)
        change_cm = -pilot.vertical_percent / 100 * self.depth_nudge_cm_per_s * step_s
        self._target_cm = min(max(self._target_cm + change_cm, _TARGET.minimum), _TARGET.maximum)
        target = round(self._target_cm)
        if target == self.commanded.target_depth_cm:
            return None
        return Command("mvd", (target,))


def is_zero_thrust(command: Command) -> bool:
    """``#th.A.0!`` or ``#mvs.+0!``: a frame that only takes thrust away."""
    return command.name in ("th", "mvs") and command.values[-1] == 0
