"""The robot's state as this tool last commanded it (P7, P9, P11).

The protocol has no query for "locked?" or "which vertical mode?", and commands that set something
are never acknowledged (P4). So a tool can only know what it sent itself; this module keeps that,
applying the controller's rules to it — a motion command while locked is dropped, ``#stop!``
clears the set-points — and words it honestly: "locked (as last sent)".

With debug output on, the controller tells every line when the lock changes
(:mod:`rovlink.protocol.announcements`); :meth:`CommandedState.hear` takes what it says, so a
``#stop!`` from another line or a failsafe shows as "locked (stopped by another line)". What is
heard never makes a tool send anything: a stop heard locks the tool as its own would (it relays
no motion, an ARM sends ``#start!`` again), but an unlock heard is only shown — the tool drives
again only once its own pilot unlocks.
"""

from __future__ import annotations

from dataclasses import dataclass

from rovlink.protocol import Command, Setting, VerticalMode
from rovlink.protocol.announcements import STOP_COMMAND, Announcement, AnnouncementKind
from rovlink.protocol.text_enum import StrEnum

__all__ = ["CommandedState", "LockState"]

_RESET_LOCK_REASON = "a suspected controller reset (locked after one)"
_RESET_MODE_REASON = "a suspected controller reset (depth mode after one)"
_REOPENED_LOCK_REASON = "the link was reopened (the controller may have reset)"


class LockState(StrEnum):
    """Whether motion is locked, as far as the commands this tool sent tell."""

    UNKNOWN = "unknown"
    LOCKED = "locked"
    UNLOCKED = "unlocked"


@dataclass(slots=True)
class CommandedState:
    """The lock, vertical mode and set-points as last sent; ``None`` where nothing was sent.

    >>> state = CommandedState()
    >>> state.apply(Command("start"))
    >>> state.apply(Command("th", (90, 30)))
    >>> state.lock_text(), state.horizontal_text()
    ('unlocked (as last sent)', '90° at 30 % (as last sent)')
    >>> state.apply(Command("stop"))
    >>> state.apply(Command("mvd", (100,)))
    'the controller drops mvd while motion is locked (as last sent): send start first'
    """

    lock: LockState = LockState.UNKNOWN
    vertical_mode: VerticalMode | None = None
    #: The depth target sent with ``mvd``; ``None``: none since the last start, stop or mode change.
    target_depth_cm: int | None = None
    #: Depth mode was entered while unlocked, so the controller holds the depth it was at.
    holding_entry_depth: bool = False
    vertical_thrust_percent: int = 0
    direction_deg: int = 0
    power_percent: int = 0
    #: The last setting or motion command sent, also one the controller drops (it was still
    #: sent: a key pressed while locked shows); queries are not kept.
    last_command: Command | None = None
    #: Why the controller drops :attr:`last_command` (as last sent); ``None`` if it acts on it.
    last_dropped_because: str | None = None
    #: :attr:`last_command` was forgotten as the link was reopened (it went on the old link).
    last_forgotten_on_reopening: bool = False

    #: Why the lock is unknown although start or stop was sent (a raw write); ``None`` if not.
    lock_unknown_because: str | None = None
    #: Why the vertical mode is unknown although mvdirect was sent; ``None`` if not.
    mode_unknown_because: str | None = None

    #: The lock as the controller announced it after this tool's last start or stop, when that
    #: differs from what the tool sent; ``None``: nothing of the kind heard since.
    heard_lock: LockState | None = None
    #: Where :attr:`heard_lock` came from: ``stopped by another line``, ``stopped by the
    #: controller: failsafe: …``, ``started by another line``.
    heard_lock_because: str | None = None
    #: :attr:`lock` as this tool had sent it when the controller was first heard to differ.
    lock_before_heard: LockState | None = None

    def forget_lock(self, why: str) -> None:
        """The lock can no longer be told from what was sent (``why``): leaving then stops."""
        self.lock = LockState.UNKNOWN
        self.lock_unknown_because = why
        self._forget_heard()

    @property
    def latest_lock(self) -> LockState:
        """The lock as last heard from the controller if it spoke since this tool's last start
        or stop, else as last sent (what the tools show)."""
        return self.heard_lock if self.heard_lock is not None else self.lock

    @property
    def sent_lock(self) -> LockState:
        """The lock as this tool itself last sent it, whatever was heard since: a tool that
        leaves stops the robot unless it locked it itself (nothing heard makes it send less
        than it would have, nor more)."""
        if self.heard_lock is None or self.lock_before_heard is None:
            return self.lock
        return self.lock_before_heard

    def hear(self, announcement: Announcement) -> bool:
        """Take what the controller announced to every line; whether the lock shown changed.

        A stop heard is taken as this tool's own (locked, set-points cleared); an unlock heard
        is shown only: :attr:`lock` stays as last sent, so nothing is relayed until the tool
        itself sends ``#start!``. An announcement of what this tool sent itself changes nothing.

        >>> state = CommandedState()
        >>> state.apply(Command("start"))
        >>> state.hear(Announcement(AnnouncementKind.UNLOCKED))  # its own start, heard back
        False
        >>> state.hear(Announcement(AnnouncementKind.LOCKED, "stop command"))
        True
        >>> state.lock_text(), str(state.lock)
        ('locked (stopped by another line)', 'locked')
        >>> state.hear(Announcement(AnnouncementKind.UNLOCKED))
        True
        >>> state.lock_text(), str(state.lock)
        ('unlocked (started by another line)', 'locked')
        """
        kind = announcement.kind
        if kind not in (AnnouncementKind.LOCKED, AnnouncementKind.UNLOCKED):
            return False
        if self.latest_lock is (
            LockState.LOCKED if kind is AnnouncementKind.LOCKED else LockState.UNLOCKED
        ):
            return False
        if self.heard_lock is None:
            self.lock_before_heard = self.lock
        if kind is AnnouncementKind.LOCKED:
            self.lock = LockState.LOCKED
            self.lock_unknown_because = None
            self._clear_set_points()
            self.heard_lock = LockState.LOCKED
            why = announcement.detail
            self.heard_lock_because = (
                "stopped by another line"
                if why == STOP_COMMAND
                else f"stopped by the controller: {why}"
            )
            return True
        self.heard_lock = LockState.UNLOCKED
        self.heard_lock_because = "started by another line"
        return True

    def _forget_heard(self) -> None:
        self.heard_lock = None
        self.heard_lock_because = None
        self.lock_before_heard = None

    def forget_after_reset(self) -> None:
        """The driver suspects a controller reset (P21): after one, the controller is locked in
        depth mode with neutral set-points, whatever was sent before; but a suspicion is no
        proof, so the lock and the mode become unknown (leaving still stops) and nothing sent
        before is taken to hold.

        >>> state = CommandedState()
        >>> state.apply(Command("start"))
        >>> state.apply(Command("th", (90, 30)))
        >>> state.forget_after_reset()
        >>> state.lock_text()
        'unknown: after a suspected controller reset (locked after one)'
        >>> state.horizontal_text()
        '0° at 0 % (as last sent)'
        """
        self.forget_lock(_RESET_LOCK_REASON)
        if self.vertical_mode is not None:
            self.vertical_mode = None
            self.mode_unknown_because = _RESET_MODE_REASON
        self._clear_set_points()

    def forget_after_reopening(self, *, stopped: bool, sent_on_it: bool = False) -> None:
        """The link was lost and reopened: the driver's first frames on it put the motion at
        rest (zero thrust), and a board reset by the reopened port (DTR) or stopped by its own
        failsafe (P17) is locked; so the lock is unknown unless ``stopped`` (a ``#stop!`` went
        on the reopened link), and the motion as last sent is at rest. The last command sent
        is forgotten unless ``sent_on_it`` (the tool's own frame went on the reopened link):
        shown, it went on the old link, and its set-points are the driver's zeros now.

        >>> state = CommandedState()
        >>> state.apply(Command("start"))
        >>> state.apply(Command("th", (90, 30)))
        >>> state.forget_after_reopening(stopped=False)
        >>> state.lock_text(), state.power_percent, state.last_command
        ('unknown: after the link was reopened (the controller may have reset)', 0, None)
        """
        self._forget_heard()  # (heard on the old link)
        if not stopped:
            self.forget_lock(_REOPENED_LOCK_REASON)
        self.power_percent = 0
        self.vertical_thrust_percent = 0
        if not sent_on_it:
            self.last_command = None
            self.last_dropped_because = None
            self.last_forgotten_on_reopening = True

    @property
    def lock_unknown_after_reset(self) -> bool:
        """Whether the lock is unknown because a controller reset is suspected."""
        return self.lock_unknown_because == _RESET_LOCK_REASON

    @property
    def lock_unknown_after_reopening(self) -> bool:
        """Whether the lock is unknown because the link was lost and reopened."""
        return self.lock_unknown_because == _REOPENED_LOCK_REASON

    @property
    def mode_unknown_after_reset(self) -> bool:
        """Whether the vertical mode is unknown because a controller reset is suspected."""
        return self.mode_unknown_because == _RESET_MODE_REASON

    def apply(self, command: Command, *, own: bool = True) -> str | None:
        """Record a command just sent; a warning if the controller will drop it, else ``None``.

        >>> state = CommandedState()
        >>> state.apply(Command("stop"))
        >>> state.apply(Command("th", (90, 30))) is not None
        True
        >>> str(state.last_command)
        '#th.90.30!'
        """
        warning = self._dropped_because(command)
        if own and not command.spec.is_query:  # (the driver's own frames are not "last sent")
            self.last_command = command
            self.last_dropped_because = warning
            self.last_forgotten_on_reopening = False
        if warning is not None:
            return warning
        name = command.name
        setting = command.setting
        if setting is not None and setting[0] is Setting.LOCKED:
            self.lock_unknown_because = None
            self._forget_heard()
            if setting[1]:  # stop
                self.lock = LockState.LOCKED
                self._clear_set_points()
            elif self.lock is not LockState.UNLOCKED:  # start
                self.lock = LockState.UNLOCKED
                self._clear_set_points()
        elif setting is not None and setting[0] is Setting.DIRECT_MODE:
            self.mode_unknown_because = None
            self._switch_mode(VerticalMode.DIRECT if setting[1] else VerticalMode.DEPTH)
        elif name == "mvs":
            (self.vertical_thrust_percent,) = command.values
        elif name == "mvd":
            (self.target_depth_cm,) = command.values
            self.holding_entry_depth = False
        elif name == "th":
            direction_deg, self.power_percent = command.values
            self.direction_deg = direction_deg % 360
        return None

    def _dropped_because(self, command: Command) -> str | None:
        spec = command.spec
        if spec.motion and self.lock is LockState.LOCKED:
            return (
                f"the controller drops {spec.name} while motion is locked (as last sent): "
                "send start first"
            )
        if (
            spec.mode is not None
            and self.vertical_mode is not None
            and spec.mode is not self.vertical_mode
        ):
            flag = 1 if spec.mode is VerticalMode.DIRECT else 0
            return (
                f"the controller drops {spec.name} in {self.vertical_mode} mode "
                f"(as last sent): send mvdirect {flag} first"
            )
        return None

    def _clear_set_points(self) -> None:
        self.target_depth_cm = None
        self.holding_entry_depth = False
        self.vertical_thrust_percent = 0
        self.direction_deg = 0
        self.power_percent = 0

    def _switch_mode(self, mode: VerticalMode) -> None:
        if mode is self.vertical_mode:
            return  # the controller changes nothing either
        self.vertical_mode = mode
        self.vertical_thrust_percent = 0
        self.target_depth_cm = None
        self.holding_entry_depth = mode is VerticalMode.DEPTH and self.lock is LockState.UNLOCKED

    # -- in words -------------------------------------------------------------------------------

    def lock_text(self) -> str:
        """``locked (as last sent)``, ``unlocked (as last sent)``, the lock heard and where
        from (``locked (stopped by another line)``), or why it is unknown."""
        if self.heard_lock is not None:
            return f"{self.heard_lock} ({self.heard_lock_because})"
        if self.lock is LockState.UNKNOWN:
            if self.lock_unknown_because is not None:
                return f"unknown: after {self.lock_unknown_because}"
            return "unknown: no start/stop sent yet (locked after a reset)"
        return f"{self.lock} (as last sent)"

    def mode_text(self) -> str:
        """The vertical mode and its set-point as last sent."""
        mode = self.vertical_mode
        if mode is None:
            if self.mode_unknown_because is not None:
                return f"unknown: after {self.mode_unknown_because}"
            return "unknown: no mvdirect sent yet (depth mode after a reset)"
        if mode is VerticalMode.DIRECT:
            return f"direct (as last sent), thrust {self.vertical_thrust_percent:+d} %"
        return f"depth (as last sent), {self.target_text()}"

    def short_lock_text(self) -> str:
        """``locked``, ``unlocked``, ``lock not sent`` or ``lock unknown`` (sent, but its
        effect cannot be told), for a line headed "as last sent"; ``locked (heard)``,
        ``unlocked (heard)`` for a lock the controller announced."""
        if self.heard_lock is not None:
            return f"{self.heard_lock} (heard)"
        if self.lock is LockState.UNKNOWN:
            return "lock not sent" if self.lock_unknown_because is None else "lock unknown"
        return str(self.lock)

    def short_mode_text(self) -> str:
        """``depth, target 100 cm``, ``direct, thrust +30 %`` or ``mode not sent``."""
        mode = self.vertical_mode
        if mode is None:
            return "mode not sent" if self.mode_unknown_because is None else "mode unknown"
        if mode is VerticalMode.DIRECT:
            return f"direct, thrust {self.vertical_thrust_percent:+d} %"
        return f"depth, {self.target_text()}"

    def target_text(self) -> str:
        """The depth target as last sent."""
        if self.target_depth_cm is not None:
            return f"target {self.target_depth_cm} cm"
        if self.holding_entry_depth:
            return "holding its depth on entry"
        return "no target sent"

    def horizontal_text(self) -> str:
        """The horizontal set-point as last sent."""
        return f"{self.direction_deg}° at {self.power_percent} % (as last sent)"
