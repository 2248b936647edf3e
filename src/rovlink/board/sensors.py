"""Sensors polled by the board loop, with the stale-sensor failsafe's bookkeeping.

The board loop polls every sensor once per control period, before the controller's tick, and
the controller reads the values kept here; so a sensor's I/O (an I²C transaction, a conversion
under way) never happens inside the controller, and a failed read is never an exception in it.
A failed poll keeps the last good value and counts; once its polls have been failing for
``stale_after_s`` (a failed poll that long after the first failed one, with no good reading
between) the sensor is *stale*, whatever the loop's rate, until it gives a good reading again.
One failed read never makes a sensor stale (unless ``stale_after_s`` is 0), however seldom
the sensor is read. A sensor the controller drives by (the pressure sensor: depth hold and the
depth limit) then stops the motors until it answers again (unless the robot is surfacing for a
leak, which needs no depth); one it only reports (the IMU: the
protocol has no yaw command, so the controller holds no heading, P11) is said to be stale and
driving goes on.
"""

from __future__ import annotations

import math
from typing import Generic, Protocol, TypeVar

from rovlink.controller import Attitude
from rovlink.logs import get_logger

__all__ = [
    "PolledImu",
    "PolledPressure",
    "PolledSensor",
    "SensorError",
    "SensorSource",
]

logger = get_logger(__name__)

_T_co = TypeVar("_T_co", covariant=True)
_T = TypeVar("_T")


class SensorError(OSError):
    """A sensor answered with data that cannot be right (a CRC mismatch, a zero conversion)."""


class SensorSource(Protocol[_T_co]):
    """A sensor's driver seen by the board loop."""

    def poll(self, now_s: float) -> _T_co | None:
        """Do this period's I/O; a new reading, or None if none is due (a conversion under way).

        Raises :class:`OSError` when the device does not answer or answers nonsense.
        """
        ...


class PolledSensor(Generic[_T]):
    """One sensor: its last good value, and since when its polls have been failing."""

    def __init__(
        self,
        name: str,
        source: SensorSource[_T],
        initial: _T,
        stale_after_s: float,
        *,
        lost_when_stale: str = "",
    ) -> None:
        """``stale_after_s``: how long polls may go on failing before the sensor is stale (0:
        at the first failure). ``lost_when_stale`` says what a stale sensor takes from the
        pilot when driving can go on without it; empty (the default) for a sensor the
        controller drives by, whose staleness stops the motors."""
        if not (isinstance(stale_after_s, float | int) and math.isfinite(stale_after_s)):
            raise ValueError(f"stale_after_s must be a number of seconds, got {stale_after_s!r}")
        if stale_after_s < 0:
            raise ValueError(f"stale_after_s must be ≥ 0, got {stale_after_s}")
        self.name = name
        self.value = initial
        self.stale_after_s = float(stale_after_s)
        self.lost_when_stale = lost_when_stale
        #: Failed polls since the last good reading.
        self.failures = 0
        self.total_failures = 0
        #: When the first of those failed (None while the last poll with I/O gave a reading).
        self.failing_since_s: float | None = None
        #: How long the polls had been failing at the last failure.
        self.failing_for_s = 0.0
        self._stale = False
        self._source = source

    @property
    def needed_to_drive(self) -> bool:
        """Whether the motors stop while this sensor is stale (the stale-sensor failsafe)."""
        return not self.lost_when_stale

    @property
    def stale(self) -> bool:
        """Whether a poll failed ``stale_after_s`` or more after the first failed poll since
        the last good reading (so a sensor read less often than that is not stale on one
        failure: it needs a second one)."""
        return self._stale

    @property
    def failing_text(self) -> str:
        """The failures since the last good reading, for a log or debug line, e.g.
        ``5 failed reads in 0.04 s``."""
        reads = "read" if self.failures == 1 else "reads"
        return f"{self.failures} failed {reads} in {self.failing_for_s:.2f} s"

    def poll(self, now_s: float) -> OSError | None:
        """Poll the source at ``now_s`` (the board clock's seconds); the error if it failed
        (the value is then kept)."""
        try:
            reading = self._source.poll(now_s)
        except OSError as error:
            self.failures += 1
            self.total_failures += 1
            if self.failing_since_s is None:
                self.failing_since_s = now_s
            self.failing_for_s = now_s - self.failing_since_s
            self._stale = self._stale or self.failing_for_s >= self.stale_after_s
            logger.debug(
                "%s: read failed (%d since the last good reading): %s",
                self.name,
                self.failures,
                error,
            )
            return error
        if reading is not None:
            if self.failures:
                logger.info("%s answers again after %d failures", self.name, self.failures)
            self.failures = 0
            self.failing_since_s = None
            self._stale = False
            self.value = reading
        return None


class PolledPressure:
    """The controller's :class:`~rovlink.controller.PressureSensor`: the last polled raw value."""

    def __init__(self, sensor: PolledSensor[int]) -> None:
        self._sensor = sensor

    def read_raw(self) -> int:
        """The last good reading on the protocol's raw scale, 0–1024."""
        return self._sensor.value


class PolledImu:
    """The controller's :class:`~rovlink.controller.Imu`: the last polled attitude."""

    def __init__(self, sensor: PolledSensor[Attitude]) -> None:
        self._sensor = sensor

    def read_attitude(self) -> Attitude:
        """The last good attitude."""
        return self._sensor.value


#: The attitude a board without an IMU reports: level, heading north.
LEVEL = Attitude(0.0, 0.0, 0.0)


def finite_attitude(roll_deg: float, pitch_deg: float, heading_deg: float) -> Attitude:
    """An :class:`Attitude`, or :class:`SensorError` if a value is not a finite number."""
    values = (roll_deg, pitch_deg, heading_deg)
    if not all(isinstance(value, float | int) and math.isfinite(value) for value in values):
        raise SensorError(f"IMU returned no attitude: {values}")
    return Attitude(float(roll_deg), float(pitch_deg), float(heading_deg) % 360.0)
