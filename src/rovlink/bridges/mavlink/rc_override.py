"""RC_CHANNELS_OVERRIDE (MAVProxy's ``rc``, joystick set-ups that speak RC) to the stick of
MANUAL_CONTROL.

ArduSub's channel map: 1 pitch, 2 roll, 3 throttle (vertical), 4 yaw, 5 forward, 6 lateral;
pulses of 1100–1900 µs, 1500 neutral. The protocol moves the robot in a direction at a power and
up or down, so channels 5 and 6 are MANUAL_CONTROL's x and y, channel 3 its z, and the others
(pitch, roll, yaw: no such commands) are ignored, as MANUAL_CONTROL's r is.

Per the MAVLink spec, on channels 1–8 a value of 0 releases the channel (back to neutral: the
robot has no radio to hand it to) and UINT16_MAX leaves it as it is. A channel keeps its value
from message to message, as ArduSub's overrides do, until the input goes stale: then every
channel is released, so input that resumes after a silence starts from neutral, as do the
overrides of a ground station that becomes the pilot's (``SYSID_MYGCS``).

A channel off neutral when the vehicle is armed is held at neutral until an override has it
back within ±40 µs of 1500 (:class:`~rovlink.bridges.mavlink.pilot_input.PilotInput` holds it,
as it holds the stick the channel drives).
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = [
    "CHANNEL_NO_CHANGE",
    "CHANNEL_OF_AXIS",
    "CHANNEL_RELEASE",
    "PWM_MAX_US",
    "PWM_MIN_US",
    "PWM_NEUTRAL_US",
    "RcOverride",
]

#: A channel value that releases the channel (channels 1–8).
CHANNEL_RELEASE = 0
#: A channel value that leaves the channel as it is (UINT16_MAX).
CHANNEL_NO_CHANGE = 65535
#: ArduSub's pulse range (RCn_MIN, RCn_MAX, RCn_TRIM): beyond it a pulse is taken as the end.
PWM_MIN_US = 1100
PWM_MAX_US = 1900
PWM_NEUTRAL_US = 1500
_THROTTLE_CHANNEL = 3
_FORWARD_CHANNEL = 5
_LATERAL_CHANNEL = 6
_FLOWN_CHANNELS = (_THROTTLE_CHANNEL, _FORWARD_CHANNEL, _LATERAL_CHANNEL)
#: The channel that drives each of MANUAL_CONTROL's axes.
CHANNEL_OF_AXIS = {"x": _FORWARD_CHANNEL, "y": _LATERAL_CHANNEL, "z": _THROTTLE_CHANNEL}
_STICK_FULL = 1000  # MANUAL_CONTROL's full deflection
_HALF_RANGE_US = (PWM_MAX_US - PWM_MIN_US) // 2


def _clamped(pulse_us: int) -> int:
    return max(PWM_MIN_US, min(PWM_MAX_US, pulse_us))


class RcOverride:
    """The overridden channels as last set, as MANUAL_CONTROL's x, y and z.

    >>> rc = RcOverride(stale_after_s=1.0)
    >>> rc.update([0, 0, 1600, 0, 1900, 0, 0, 0], now_s=0.0)  # MAVProxy: rc 3 1600, rc 5 1900
    (1000, 0, 625)
    >>> rc.update([65535] * 4 + [1300] + [65535] * 3, now_s=0.1)  # channel 5 alone changes
    (-500, 0, 625)
    >>> rc.update([65535] * 8, now_s=2.0)  # after a silence: released
    (0, 0, 500)
    """

    def __init__(self, stale_after_s: float) -> None:
        self.stale_after_s = stale_after_s
        self._pulses_us = dict.fromkeys(_FLOWN_CHANNELS, PWM_NEUTRAL_US)
        self._last_at_s: float | None = None

    def release(self) -> None:
        """Every channel back to neutral (input gone stale, or another ground station flies:
        its overrides start from neutral, not from the channels the last one set)."""
        self._pulses_us = dict.fromkeys(_FLOWN_CHANNELS, PWM_NEUTRAL_US)

    def update(self, channels: Sequence[int], now_s: float) -> tuple[int, int, int]:
        """Take one message's channels (``channels[0]`` is channel 1); the stick they make:
        x (forward) and y (right) in −1000…1000, z (throttle) in 0…1000 with 500 neutral."""
        if self._last_at_s is not None and now_s - self._last_at_s >= self.stale_after_s:
            self.release()
        self._last_at_s = now_s
        for channel in _FLOWN_CHANNELS:
            raw = channels[channel - 1]
            if raw == CHANNEL_NO_CHANGE:
                continue
            self._pulses_us[channel] = PWM_NEUTRAL_US if raw == CHANNEL_RELEASE else _clamped(raw)
        return (
            self._deflection(_FORWARD_CHANNEL),
            self._deflection(_LATERAL_CHANNEL),
            (self._deflection(_THROTTLE_CHANNEL) + _STICK_FULL) // 2,
        )

    def _deflection(self, channel: int) -> int:
        """The channel's pulse as −1000…1000 (1100 µs: −1000, 1500: 0, 1900: 1000)."""
        offset_us = self._pulses_us[channel] - PWM_NEUTRAL_US
        return round(offset_us * _STICK_FULL / _HALF_RANGE_US)
