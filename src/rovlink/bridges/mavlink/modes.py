"""ArduSub's flight modes and joystick button functions, as far as the protocol can serve them."""

from __future__ import annotations

from enum import IntEnum

__all__ = ["SUPPORTED_BUTTON_FUNCTIONS", "ButtonFunction", "FlightMode"]


class FlightMode(IntEnum):
    """ArduSub's custom mode numbers (HEARTBEAT ``custom_mode``) that the bridge serves.

    MANUAL is the controller's direct vertical mode (``#mvdirect.1!``: the pilot's throttle is
    vertical thrust); ALT_HOLD is its depth mode (``#mvdirect.0!``: the controller's PID holds a
    depth the pilot's throttle moves). The protocol has no attitude control, so STABILIZE (0) and
    the other ArduSub modes are refused.
    """

    ALT_HOLD = 2
    MANUAL = 19


class ButtonFunction(IntEnum):
    """ArduSub's joystick button functions (``BTNn_FUNCTION`` values) the bridge acts on."""

    NONE = 0
    ARM_TOGGLE = 2
    ARM = 3
    DISARM = 4
    MODE_MANUAL = 5
    MODE_DEPTH_HOLD = 7


#: Values a ``BTNn_FUNCTION`` parameter accepts: the functions the bridge can carry out.
SUPPORTED_BUTTON_FUNCTIONS = frozenset(int(function) for function in ButtonFunction)
