"""The hardware-abstraction layer: everything the controller knows of its board.

The controller reads sensors and drives outputs only through these typed protocols, so the same
logic runs against the simulator (:mod:`rovlink.sim`), against fakes in tests, or against real
boards. Every method is called from the controller's single thread of control and must not block.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Protocol

__all__ = [
    "Attitude",
    "ClawMotor",
    "Clock",
    "Hardware",
    "Imu",
    "LeakSensor",
    "PressureSensor",
    "ThrusterOutputs",
]


class Attitude(NamedTuple):
    """One IMU reading, degrees: roll (+ starboard down), pitch (+ bow up), magnetic heading."""

    roll_deg: float
    pitch_deg: float
    heading_deg: float


class Clock(Protocol):
    """A monotonic clock in seconds (simulated or real)."""

    def now_s(self) -> float:
        """Seconds since an arbitrary, fixed origin; never decreases."""
        ...


class ThrusterOutputs(Protocol):
    """The PWM outputs of every thruster of the configured layout, in layout order."""

    def set_duties(self, duties: Sequence[int]) -> None:
        """Apply signed duties −255…+255; + pushes along the thruster's axis (up, if vertical)."""
        ...


class PressureSensor(Protocol):
    """The pressure sensor behind its analog-to-digital converter."""

    def read_raw(self) -> int:
        """One conversion, 0–1024."""
        ...


class Imu(Protocol):
    """The inertial measurement unit with its magnetic compass."""

    def read_attitude(self) -> Attitude:
        """The current roll, pitch and heading."""
        ...


class LeakSensor(Protocol):
    """The leak-detector input, latched in hardware (an interrupt flag) so no pulse is missed."""

    def fired_since_last_read(self) -> bool:
        """Whether the input was wet at any moment since the previous call; clears the flag."""
        ...


class ClawMotor(Protocol):
    """The claw's motor driver."""

    def drive(self, direction: int) -> None:
        """Run the motor: +1 opens, −1 closes, 0 stops."""
        ...


@dataclass(frozen=True, slots=True)
class Hardware:
    """The board as the controller sees it: one object per device."""

    thrusters: ThrusterOutputs
    pressure: PressureSensor
    imu: Imu
    leak: LeakSensor
    claw: ClawMotor
    clock: Clock
