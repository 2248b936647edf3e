"""What a board gives the board loop: its devices, its sensors to poll, and its safe state."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

from rovlink.board.sensors import PolledSensor
from rovlink.controller import Hardware

__all__ = ["Board", "BoardStartError", "DeviceCheck", "MonotonicClock"]


class BoardStartError(Exception):
    """A board that cannot start: the message names the device, where it is, and why."""


class MonotonicClock:
    """The controller's clock on a real board: :func:`time.monotonic`."""

    def now_s(self) -> float:
        """Seconds since an arbitrary origin; never decreases."""
        return time.monotonic()


class DeviceCheck(Protocol):
    """An output device the board loop checks every control period (a PWM chip that may have
    reset behind the driver's back), repairing what it finds."""

    @property
    def name(self) -> str:
        """The device, as log lines and debug lines name it."""
        ...

    def is_due(self, now_s: float) -> bool:
        """Whether a check is due (checks cost bus time: they run at a rate of their own)."""
        ...

    def check(self, now_s: float) -> str | None:
        """Check the device now; a fault found and what was done about it (the outputs then at
        neutral, or without pulses while a repair fails), or None.

        Raises :class:`OSError` when the device does not answer the check.
        """
        ...


@dataclass
class Board:
    """An opened board, its outputs already at rest.

    ``make_safe`` puts every thrust output at neutral, written to the device even if it is
    believed to be there already, and raises if it cannot; ``close`` releases the devices
    (leaving the outputs as they are: at neutral, after ``make_safe``). ``checks`` are looked at
    every control period and run when due; a fault they find stops and locks the controller.
    """

    name: str
    hardware: Hardware
    make_safe: Callable[[], None]
    close: Callable[[], None]
    sensors: Sequence[PolledSensor[Any]] = field(default_factory=tuple)
    checks: Sequence[DeviceCheck] = field(default_factory=tuple)
    #: What the board started without (a dead IMU), for the controller's ready line.
    warnings: Sequence[str] = field(default_factory=tuple)
    #: What an I/O failure of the board means (its bus probed: one device gone, or the whole
    #: bus stuck) and what to do, for the failure's message; None: nothing to probe.
    diagnose: Callable[[], str] | None = None
