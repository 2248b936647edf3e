"""What the ground station is told: the robot's readings in MAVLink's units and frames.

The readings come from ``#qsa!`` (depth, raw pressure, leak latch, roll, pitch, heading); the
lock and mode are the ones last sent. MAVLink's altitude is up-positive, so altitude = −depth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rovlink.bridges.mavlink.modes import FlightMode
from rovlink.client.sensors import Sensors

__all__ = ["SURFACE_PRESSURE_HPA", "WATER_HPA_PER_M", "VehicleState"]

#: Standard atmosphere at the surface, hPa.
SURFACE_PRESSURE_HPA = 1013.25
#: Pressure of one metre of fresh water (1000 kg/m³ · 9.80665 m/s²), hPa.
WATER_HPA_PER_M = 98.0665
#: Weight of the newest climb-rate sample in the running average (depth steps are 1 cm).
_CLIMB_WEIGHT = 0.3
#: The least time between the two readings of a climb-rate sample, s: readings that come close
#: together (a poll caught up after a missed one, two replies in one read) would divide a 1 cm
#: step or a sensor's noise by a few milliseconds, and show metres a second.
_CLIMB_MIN_INTERVAL_S = 0.1


@dataclass(slots=True)
class VehicleState:
    """The latest readings and the flight mode, with the values MAVLink messages carry.

    >>> from rovlink.client.sensors import Sensors
    >>> state = VehicleState()
    >>> state.update(Sensors(150, 95, False, -2, 3, 270), now_s=1.0)
    False
    >>> state.altitude_m(), round(math.degrees(state.attitude_rad()[2]))
    (-1.5, -90)
    """

    mode: FlightMode = FlightMode.MANUAL
    sensors: Sensors | None = None
    #: Vertical speed from successive depth readings, cm/s, + up (MAVLink's climb).
    climb_cm_s: float = 0.0
    #: Whether :attr:`sensors` is the robot as it is: no reading was missed since.
    current: bool = False
    #: The reading a climb-rate sample starts from: when, s, and its depth, cm.
    _reference_at_s: float | None = None
    _reference_depth_cm: int = 0

    def update(self, sensors: Sensors, now_s: float) -> bool:
        """Take a new reading; ``True`` when it is the first to show a leak."""
        previous = self.sensors
        if self._reference_at_s is None:
            self._reference_at_s, self._reference_depth_cm = now_s, sensors.depth_cm
        elif now_s - self._reference_at_s >= _CLIMB_MIN_INTERVAL_S:
            climb = (self._reference_depth_cm - sensors.depth_cm) / (now_s - self._reference_at_s)
            self.climb_cm_s += _CLIMB_WEIGHT * (climb - self.climb_cm_s)
            self._reference_at_s, self._reference_depth_cm = now_s, sensors.depth_cm
        self.sensors = sensors
        self.current = True
        return sensors.leak_detected and (previous is None or not previous.leak_detected)

    def missed(self) -> None:
        """A reading did not come (the controller did not answer, its link is down): the last
        one is no longer current, and the climb rate starts again from the next two, not
        averaged with the speed of before the gap."""
        self.current = False
        self.climb_cm_s = 0.0
        self._reference_at_s = None

    @property
    def depth_cm(self) -> int | None:
        """Depth of the latest reading, cm."""
        return None if self.sensors is None else self.sensors.depth_cm

    @property
    def leak(self) -> bool:
        """Whether the latest reading shows the leak latch set."""
        return self.sensors is not None and self.sensors.leak_detected

    def altitude_m(self) -> float:
        """MAVLink altitude: −depth, m (0 before the first reading)."""
        return 0.0 if self.sensors is None else -self.sensors.depth_cm / 100.0

    def heading_deg(self) -> int:
        """Heading 0–359°."""
        return 0 if self.sensors is None else self.sensors.heading_deg % 360

    def attitude_rad(self) -> tuple[float, float, float]:
        """Roll, pitch and yaw in radians, yaw in −π…π as ATTITUDE has it."""
        if self.sensors is None:
            return 0.0, 0.0, 0.0
        yaw_deg = self.heading_deg()
        if yaw_deg > 180:
            yaw_deg -= 360
        return (
            math.radians(self.sensors.roll_deg),
            math.radians(self.sensors.pitch_deg),
            math.radians(yaw_deg),
        )

    def absolute_pressure_hpa(self, zero_raw: int, k: int) -> float:
        """Water pressure from the raw reading and the depth calibration (P13), hPa.

        The calibration says depth[m] = (raw − zero) · k / 10000; the pressure is the surface's
        plus that much fresh water (not clamped at the surface, unlike ``qd``).
        """
        if self.sensors is None:
            return SURFACE_PRESSURE_HPA
        depth_m = (self.sensors.pressure_raw - zero_raw) * k / 10000
        return SURFACE_PRESSURE_HPA + depth_m * WATER_HPA_PER_M
