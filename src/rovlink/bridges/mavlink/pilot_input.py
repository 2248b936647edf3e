"""MANUAL_CONTROL (a ground station's joystick) to the commands of the protocol.

x (forward) and y (right), −1000…1000, become ``#th.A.P!``: the direction the stick points,
clockwise from the bow, and the stick's deflection as power. z, 0…1000 with 500 neutral, is
vertical thrust (``#mvs!``) in MANUAL and moves the held depth (``#mvd!``) in ALT_HOLD. r (yaw)
is ignored: the protocol has no yaw command. Buttons 0–15 (``buttons``) and 16–31 (the extension
``buttons2``) carry out their ``BTNn_FUNCTION`` once per press. RC_CHANNELS_OVERRIDE's channels
(:mod:`rc_override`) drive the same stick, without buttons. Only changes are sent, so a joystick
at 50 Hz does not fill the serial line.

Input that stops coming for :data:`INPUT_STALE_S` (P23) is expired with zero thrust.

An axis off centre when the vehicle is armed is held at neutral until it has been seen centred
(within :data:`CENTRE_BAND` of full, the throttle's depth-hold dead band): an RC override set
while disarmed, or left from before a disarm, is repeated by its ground station and would
otherwise drive the robot the moment it is armed, without a fresh pilot input; so would a
joystick held (or drifting) off centre as the arm button is pressed. The same holds when another
ground station becomes the pilot's while armed (:meth:`PilotInput.new_pilot`): the first input
of its stick, which may have been off centre all along, is held likewise; and a button it
holds in its first input with buttons counts only once released and pressed again (held while
its joystick was ignored, it would otherwise arm, disarm or change the mode at the hand-over).
A button held at arming needs no such care: the pilot's buttons are followed armed or not, so
a press is a press once, whenever it came.

What "changed" and "zero" are measured against is the set-points as last sent to the controller
(:meth:`PilotInput.sync`), never a guess: the controller keeps its thrust across a repeated
``#start!`` or ``#mvdirect`` (P7, P9, P11), so a bridge that took those as neutral would never
zero thrust the robot still has.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rovlink.bridges.mavlink.modes import ButtonFunction, FlightMode
from rovlink.bridges.mavlink.parameters import BUTTON_COUNT, ParameterTable
from rovlink.piloting.commanded import CommandedState
from rovlink.protocol import Command, lookup

__all__ = [
    "AXIS_UNUSED",
    "CENTRE_BAND",
    "INPUT_STALE_S",
    "MAX_CLIMB_CM_S",
    "PilotInput",
    "PilotOutput",
    "all_buttons",
    "horizontal",
    "vertical_thrust_percent",
]

#: MANUAL_CONTROL's value for an axis the ground station does not use.
AXIS_UNUSED = 32767
#: MANUAL_CONTROL older than this is stale: motion expires (PROTOCOL.md P23).
INPUT_STALE_S = 1.0
#: ALT_HOLD: how fast a full throttle stick moves the held depth, cm/s.
MAX_CLIMB_CM_S = 50.0
#: ALT_HOLD: throttle within this of neutral (of 500) leaves the held depth alone.
_THROTTLE_DEADBAND = 50
#: x and y within this of 0 (of 1000) count as centred, as z within the dead band of 500.
CENTRE_BAND = 100
#: Longest gap between inputs that moves the held depth (a gap is not a held stick).
_MAX_STEP_S = 0.2
_NEUTRAL_Z = 500
_FULL_Z = 1000
_DEPTH_RANGE = lookup("mvd").arguments[0]
_THRUST_RANGE = lookup("mvs").arguments[0]
_POWER_RANGE = lookup("th").arguments[1]


def _axis(value: int, unused: int = 0) -> int:
    return unused if value == AXIS_UNUSED else value


_NEUTRAL_AXES = {"x": 0, "y": 0, "z": _NEUTRAL_Z}
_CENTRE_BANDS = {"x": CENTRE_BAND, "y": CENTRE_BAND, "z": _THROTTLE_DEADBAND}


def _centred(axis: str, value: int) -> bool:
    return abs(value - _NEUTRAL_AXES[axis]) <= _CENTRE_BANDS[axis]


def all_buttons(buttons: int, buttons2: int) -> int:
    """MANUAL_CONTROL's 32 buttons as one bit field: ``buttons`` 0–15, ``buttons2`` 16–31.

    >>> all_buttons(1 << 6, 1) == 1 << 6 | 1 << 16
    True
    """
    return (buttons & 0xFFFF) | (buttons2 & 0xFFFF) << 16


def horizontal(x: int, y: int) -> tuple[int, int]:
    """Direction (clockwise from the bow, 0–359°) and power (%) of the stick at x, y.

    >>> horizontal(1000, 0), horizontal(0, 500), horizontal(-1000, 0), horizontal(0, -250)
    ((0, 100), (90, 50), (180, 100), (270, 25))
    """
    power = min(_POWER_RANGE.maximum, round(math.hypot(x, y) / 10))
    direction = round(math.degrees(math.atan2(y, x))) % 360
    return direction, power


def vertical_thrust_percent(z: int) -> int:
    """Vertical thrust for throttle z (0…1000, 500 neutral), + up.

    >>> vertical_thrust_percent(500), vertical_thrust_percent(1000), vertical_thrust_percent(250)
    (0, 100, -50)
    """
    thrust = round((z - _NEUTRAL_Z) / 5)
    return max(_THRUST_RANGE.minimum, min(_THRUST_RANGE.maximum, thrust))


@dataclass(frozen=True, slots=True)
class PilotOutput:
    """What one MANUAL_CONTROL asks for: commands to send, button functions pressed, the
    axes ("x", "y", "z") this input found held off centre since arming, each said once, and the
    buttons with a function that a new pilot's first input holds (not pressed: said once)."""

    commands: tuple[Command, ...] = ()
    pressed: tuple[ButtonFunction, ...] = ()
    newly_held: tuple[str, ...] = ()
    held_buttons: tuple[int, ...] = ()


class PilotInput:
    """The pilot's stick and buttons, turned into commands (changes only) and expired when stale.

    >>> from rovlink.bridges.mavlink.parameters import ParameterTable
    >>> pilot = PilotInput(ParameterTable())
    >>> out = pilot.manual_control(1000, 0, 600, 0, mode=FlightMode.MANUAL, armed=True, now_s=0.0)
    >>> [str(command) for command in out.commands]
    ['#th.0.100!', '#mvs.+20!']
    >>> [str(command) for command in pilot.expire(now_s=1.5)]
    ['#th.0.0!', '#mvs.+0!']
    """

    def __init__(self, parameters: ParameterTable, *, stale_after_s: float = INPUT_STALE_S) -> None:
        self._parameters = parameters
        self.stale_after_s = stale_after_s
        self.last_input_at_s: float | None = None
        self._buttons = 0
        self._direction_deg = 0
        self._power_percent = 0
        self._thrust_percent = 0
        self._target_depth_cm: float | None = None
        self._sent_depth_cm: int | None = None
        #: The last input's axes (x, y, throttle z), armed or not: the stick as it is at arming.
        self._stick = {"x": 0, "y": 0, "z": _NEUTRAL_Z}
        self._held_axes: set[str] = set()
        self._said_held_axes: set[str] = set()
        #: Another pilot flies and has sent no input yet: its first input's axes are held.
        self._hold_first_input = False
        #: Another pilot flies and has sent no buttons yet: the first it sends are not pressed.
        self._buttons_unknown = False

    @property
    def moving(self) -> bool:
        """Whether the last commands sent asked for thrust."""
        return self._power_percent != 0 or self._thrust_percent != 0

    @property
    def target_depth_cm(self) -> int | None:
        """ALT_HOLD: the depth held, as last sent."""
        return self._sent_depth_cm

    def sync(self, sent: CommandedState) -> None:
        """Adopt the set-points as last sent to the controller, its rules applied (after every
        frame sent: ``#stop!`` clears them, a repeated ``#start!`` or ``#mvdirect`` keeps them).

        The stick's changes, a centred stick and stale input are then measured against the thrust
        the controller really has.
        """
        self._direction_deg = sent.direction_deg
        self._power_percent = sent.power_percent
        self._thrust_percent = sent.vertical_thrust_percent
        if sent.target_depth_cm != self._sent_depth_cm:  # same: keep the stick's fraction of a cm
            self._sent_depth_cm = sent.target_depth_cm
            depth = sent.target_depth_cm
            self._target_depth_cm = None if depth is None else float(depth)

    def hold_off_centre_axes(self) -> None:
        """On arming (and every re-arm): the axes off centre in the last input are held at
        neutral until an input has them centred (MAVProxy repeats an override set while
        disarmed; a joystick may be held over as the arm button is pressed)."""
        self._held_axes = {axis for axis, value in self._stick.items() if not _centred(axis, value)}
        self._said_held_axes = set()

    def new_pilot(self) -> None:
        """Another ground station flies from now on: the stick last seen is no longer its own.

        Its first input, armed, has the axes off centre held at neutral until centred, as at
        arming (its stick, ignored until now, may be held over; its overrides set long since).
        Disarmed, that input is the stick as it is when the vehicle is armed. The buttons its
        first input with buttons holds, armed or not, count only once released and pressed.
        """
        self._hold_first_input = True
        self._buttons_unknown = True

    def hold(self, depth_cm: int) -> Command:
        """ALT_HOLD from now on holds ``depth_cm``: the command that says so."""
        depth = max(_DEPTH_RANGE.minimum, min(_DEPTH_RANGE.maximum, depth_cm))
        self._target_depth_cm = float(depth)
        self._sent_depth_cm = depth
        return Command("mvd", (depth,))

    def manual_control(
        self,
        x: int,
        y: int,
        z: int,
        buttons: int | None,
        *,
        mode: FlightMode,
        armed: bool,
        now_s: float,
    ) -> PilotOutput:
        """Take one MANUAL_CONTROL (``buttons`` 0–31 as :func:`all_buttons` joins them; ``None``
        for input without buttons, an RC override: they stay as they were); the commands that
        carry out what changed."""
        previous_at_s = self.last_input_at_s
        self.last_input_at_s = now_s
        held_buttons: tuple[int, ...] = ()
        if buttons is not None and self._buttons_unknown:  # a new pilot's first buttons
            self._buttons_unknown = False
            self._buttons = buttons
            held_buttons = tuple(
                button for button in self._functional_buttons() if buttons & (1 << button)
            )
        pressed = () if buttons is None else self._pressed(buttons)
        # ArduSub's 0…1000 (MAVLink's common range is −1000…1000): beyond it, full throttle.
        throttle = max(0, min(_FULL_Z, _axis(z, _NEUTRAL_Z)))
        self._stick = {"x": _axis(x), "y": _axis(y), "z": throttle}
        if self._hold_first_input:  # a new pilot's first input
            self._hold_first_input = False
            if armed:
                self.hold_off_centre_axes()
        if not armed:  # the controller drops motion while locked (P7): nothing to send
            return PilotOutput((), pressed, held_buttons=held_buttons)
        stick, newly_held = self._released_axes()
        commands: list[Command] = []
        direction, power = horizontal(stick["x"], stick["y"])
        if power == 0:
            direction = self._direction_deg  # zero power keeps the last direction, as the session
        if (direction, power) != (self._direction_deg, self._power_percent) and (
            power or self._power_percent
        ):
            commands.append(Command("th", (direction, power)))
            self._direction_deg, self._power_percent = direction, power
        throttle = stick["z"]
        if mode is FlightMode.MANUAL:
            thrust = vertical_thrust_percent(throttle)
            if thrust != self._thrust_percent:
                commands.append(Command("mvs", (thrust,)))
                self._thrust_percent = thrust
        elif self._target_depth_cm is not None and previous_at_s is not None:
            step_s = min(max(now_s - previous_at_s, 0.0), _MAX_STEP_S)
            offset = throttle - _NEUTRAL_Z
            if abs(offset) > _THROTTLE_DEADBAND:
                climb_cm_s = offset / _NEUTRAL_Z * MAX_CLIMB_CM_S
                self._target_depth_cm = max(
                    float(_DEPTH_RANGE.minimum),
                    min(float(_DEPTH_RANGE.maximum), self._target_depth_cm - climb_cm_s * step_s),
                )
                depth = round(self._target_depth_cm)
                if depth != self._sent_depth_cm:
                    commands.append(Command("mvd", (depth,)))
                    self._sent_depth_cm = depth
        return PilotOutput(tuple(commands), pressed, newly_held, held_buttons)

    def _released_axes(self) -> tuple[dict[str, int], tuple[str, ...]]:
        """The last input with each axis still held at neutral; the axes newly found held."""
        self._held_axes -= {axis for axis, value in self._stick.items() if _centred(axis, value)}
        newly_held = tuple(sorted(self._held_axes - self._said_held_axes))
        self._said_held_axes |= self._held_axes
        stick = {
            axis: _NEUTRAL_AXES[axis] if axis in self._held_axes else value
            for axis, value in self._stick.items()
        }
        return stick, newly_held

    def expire(self, now_s: float) -> tuple[Command, ...]:
        """Zero thrust if the input went stale while it asked for thrust (once), else nothing."""
        if self.last_input_at_s is None or now_s - self.last_input_at_s < self.stale_after_s:
            return ()
        commands = []
        if self._power_percent:
            commands.append(Command("th", (self._direction_deg, 0)))
            self._power_percent = 0
        if self._thrust_percent:
            commands.append(Command("mvs", (0,)))
            self._thrust_percent = 0
        return tuple(commands)

    def _pressed(self, buttons: int) -> tuple[ButtonFunction, ...]:
        rising = buttons & ~self._buttons
        self._buttons = buttons
        return tuple(
            self._parameters.button_function(button)
            for button in self._functional_buttons()
            if rising & (1 << button)
        )

    def _functional_buttons(self) -> list[int]:
        """The buttons whose ``BTNn_FUNCTION`` is not NONE, in order."""
        return [
            button
            for button in range(BUTTON_COUNT)
            if self._parameters.button_function(button) is not ButtonFunction.NONE
        ]
