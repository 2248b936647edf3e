"""The Bosch BNO055 IMU through Adafruit's maintained CircuitPython driver.

The chip fuses accelerometer, gyroscope and magnetometer itself (NDOF mode); this wraps the
driver's Euler angles as the controller's attitude, with the chip's own axis remap for the
mounting (datasheet §3.4, placements P0–P7) and the signs and heading offset of the frame.
"""

from __future__ import annotations

import time
from typing import Any, NoReturn

from rovlink.board.pi.i2c import BusioAdapter, I2cBus, check_address
from rovlink.board.sensors import SensorError, finite_attitude
from rovlink.controller import Attitude
from rovlink.logs import get_logger

__all__ = ["PLACEMENTS", "Bno055Imu", "remap_for_placement"]

logger = get_logger(__name__)

#: How often a chip out of fusion mode is put back (each time takes about 60 ms of mode
#: changes, which the datasheet's switching times impose).
_FUSION_RESTART_INTERVAL_S = 1.0

#: Datasheet table 3-5: placement → (AXIS_MAP_CONFIG, AXIS_MAP_SIGN).
PLACEMENTS: dict[str, tuple[int, int]] = {
    "P0": (0x21, 0x04),
    "P1": (0x24, 0x00),  # the chip's default
    "P2": (0x24, 0x06),
    "P3": (0x21, 0x02),
    "P4": (0x24, 0x03),
    "P5": (0x21, 0x01),
    "P6": (0x21, 0x07),
    "P7": (0x24, 0x05),
}


def remap_for_placement(placement: str) -> tuple[int, int, int, int, int, int]:
    """The driver's ``axis_remap`` tuple (x, y, z, x_sign, y_sign, z_sign) for a placement.

    >>> remap_for_placement("P1"), remap_for_placement("P0")
    ((0, 1, 2, 0, 0, 0), (1, 0, 2, 1, 0, 0))
    """
    config, sign = PLACEMENTS[placement]
    return (
        config & 0x03,
        (config >> 2) & 0x03,
        (config >> 4) & 0x03,
        (sign >> 2) & 0x01,
        (sign >> 1) & 0x01,
        sign & 0x01,
    )


class Bno055Imu:
    """A BNO055 in NDOF fusion mode, read at most ``poll_hz`` times a second."""

    def __init__(
        self,
        bus: I2cBus,
        *,
        address: int = 0x28,
        placement: str = "P1",
        heading_offset_deg: float = 0.0,
        invert_roll: bool = False,
        invert_pitch: bool = False,
        poll_hz: float = 20.0,
    ) -> None:
        if placement not in PLACEMENTS:
            raise ValueError(f"placement must be one of {', '.join(PLACEMENTS)}, got {placement!r}")
        self.bus = bus
        self.address = check_address(address)
        self.placement = placement
        self._heading_offset_deg = heading_offset_deg
        self._roll_sign = -1.0 if invert_roll else 1.0
        self._pitch_sign = -1.0 if invert_pitch else 1.0
        self._interval_s = 1.0 / poll_hz
        self._next_s = 0.0
        self._next_fusion_restart_s = 0.0
        self._sensor: Any = None
        #: How often the chip was found out of fusion mode and put back.
        self.fusion_restarts = 0

    def start(self) -> None:
        """Reset the chip into fusion mode (about a second) and apply the placement."""
        import adafruit_bno055  # noqa: PLC0415 - the pi extra, needed on the board only

        sensor = adafruit_bno055.BNO055_I2C(BusioAdapter(self.bus), self.address)
        if self.placement != "P1":
            sensor.axis_remap = remap_for_placement(self.placement)
        self._sensor = sensor
        time.sleep(0.02)

    def _out_of_fusion(self, now_s: float) -> NoReturn:
        """The chip is in config mode: it was reset (a supply dip, its own watchdog) and lost
        its mode and axis map. Put both back (at most once a ``_FUSION_RESTART_INTERVAL_S``),
        then raise: this poll has no attitude."""
        name = f"BNO055 at {self.address:#04x}"
        if now_s < self._next_fusion_restart_s:
            raise SensorError(f"{name}: out of fusion mode")
        self._next_fusion_restart_s = now_s + _FUSION_RESTART_INTERVAL_S
        import adafruit_bno055  # noqa: PLC0415 - the pi extra, needed on the board only

        self.fusion_restarts += 1
        logger.warning("%s out of fusion mode (reset?): setting fusion mode again", name)
        sensor = self._sensor
        if self.placement != "P1":
            sensor.axis_remap = remap_for_placement(self.placement)
        sensor.mode = adafruit_bno055.NDOF_MODE
        raise SensorError(
            f"{name}: out of fusion mode (reset?): fusion mode and placement {self.placement} "
            "set again; its calibration starts over"
        )

    def poll(self, now_s: float) -> Attitude | None:
        """A new attitude if one is due."""
        if now_s < self._next_s:
            return None
        self._next_s = now_s + self._interval_s
        # The driver's order is heading, roll, pitch; None while fusion is not running.
        heading, roll, pitch = self._sensor.euler
        if roll is None or pitch is None or heading is None:
            self._out_of_fusion(now_s)
        if not (0.0 <= heading <= 360.0 and -90.0 <= roll <= 90.0 and -180.0 <= pitch <= 180.0):
            # Outside the datasheet's ranges: a corrupt read (on a Pi 3/4's I²C, a byte
            # misread while the chip stretched the clock), never an attitude.
            raise SensorError(
                f"BNO055 at {self.address:#04x}: heading {heading:g}°, roll {roll:g}°, pitch "
                f"{pitch:g}° are outside the datasheet's 0–360°, ±90°, ±180°: a corrupt read"
            )
        return finite_attitude(
            self._roll_sign * roll,
            self._pitch_sign * pitch,
            heading + self._heading_offset_deg,
        )
