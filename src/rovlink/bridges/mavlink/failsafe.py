"""The ground-station failsafe: no word from the pilot's ground station for 3 s while armed →
``#stop!``.

ArduSub's pilot-input failsafe only runs once a pilot has sent input and can be disabled; this
one has no gaps: it watches the ground station's HEARTBEAT from the moment the robot is armed
(arming counts as contact), whatever the mode, whether or not a joystick was ever used, and
cannot be switched off. The pilot's joystick (MANUAL_CONTROL, RC overrides) is contact too, as
in ArduSub. Stale joystick input is :mod:`pilot_input`'s part.
"""

from __future__ import annotations

__all__ = ["GCS_TIMEOUT_S", "GcsWatchdog"]

#: Seconds without a ground-station HEARTBEAT after which an armed robot is stopped.
GCS_TIMEOUT_S = 3.0


class GcsWatchdog:
    """Tells when the ground station went silent while the robot was armed.

    >>> watchdog = GcsWatchdog()
    >>> watchdog.heartbeat(now_s=0.0)
    >>> watchdog.tripped(now_s=2.9, armed=True), watchdog.tripped(now_s=3.1, armed=True)
    (False, True)
    >>> watchdog.tripped(now_s=3.2, armed=True)  # once per silence
    False
    """

    def __init__(self, timeout_s: float = GCS_TIMEOUT_S) -> None:
        self.timeout_s = timeout_s
        self.last_heartbeat_at_s: float | None = None
        self._tripped = False

    def heartbeat(self, now_s: float) -> None:
        """A ground station's HEARTBEAT or joystick input arrived (or the robot was armed by
        one)."""
        self.last_heartbeat_at_s = now_s
        self._tripped = False

    def silent_s(self, now_s: float) -> float | None:
        """Seconds since the last ground-station contact; ``None`` before the first."""
        return None if self.last_heartbeat_at_s is None else now_s - self.last_heartbeat_at_s

    def tripped(self, now_s: float, *, armed: bool) -> bool:
        """``True`` once when an armed robot has not heard a ground station for the timeout."""
        if not armed or self._tripped:
            return False
        silent_s = self.silent_s(now_s)
        if silent_s is None or silent_s >= self.timeout_s:
            self._tripped = True
            return True
        return False
