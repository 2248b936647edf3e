"""What a board gives the board loop: its devices, its sensors to poll, and its safe state."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from rovlink.board.sensors import PolledSensor
from rovlink.controller import Hardware

__all__ = ["Board", "BoardStartError", "MonotonicClock"]


class BoardStartError(Exception):
    """A board that cannot start: the message names the device, where it is, and why."""


class MonotonicClock:
    """The controller's clock on a real board: :func:`time.monotonic`."""

    def now_s(self) -> float:
        """Seconds since an arbitrary origin; never decreases."""
        return time.monotonic()


@dataclass
class Board:
    """An opened board, its outputs already at rest.

    ``make_safe`` puts every thrust output at neutral, written to the device even if it is
    believed to be there already, and raises if it cannot; ``close`` releases the devices
    (leaving the outputs as they are: at neutral, after ``make_safe``).
    """

    name: str
    hardware: Hardware
    make_safe: Callable[[], None]
    close: Callable[[], None]
    sensors: Sequence[PolledSensor[Any]] = field(default_factory=tuple)
