"""A controller on fake hardware with a hand-driven clock: every test is exact and instant."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from rovlink.controller import Attitude, Controller, ControllerConfig, Hardware

TICK_S = 0.01


class FakeClock:
    def __init__(self) -> None:
        self.time_s = 0.0

    def now_s(self) -> float:
        return self.time_s


class FakeThrusters:
    def __init__(self) -> None:
        self.duties: tuple[int, ...] = ()
        self.writes = 0

    def set_duties(self, duties: Sequence[int]) -> None:
        self.duties = tuple(duties)
        self.writes += 1


class FakePressure:
    def __init__(self) -> None:
        self.raw = 20  # the surface, with the default calibration

    def read_raw(self) -> int:
        return self.raw


class FakeImu:
    def __init__(self) -> None:
        self.attitude = Attitude(0.0, 0.0, 0.0)

    def read_attitude(self) -> Attitude:
        return self.attitude


class FakeLeak:
    def __init__(self) -> None:
        self.pending = False

    def pulse(self) -> None:
        self.pending = True

    def fired_since_last_read(self) -> bool:
        fired, self.pending = self.pending, False
        return fired


class FakeClaw:
    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock
        self.direction = 0
        self.history: list[tuple[float, int]] = []

    def drive(self, direction: int) -> None:
        self.direction = direction
        self.history.append((self.clock.time_s, direction))


@dataclass
class Rig:
    """The controller and its fake board."""

    controller: Controller
    clock: FakeClock
    thrusters: FakeThrusters
    pressure: FakePressure
    imu: FakeImu
    leak: FakeLeak
    claw: FakeClaw
    written: list[bytes] = field(default_factory=list)

    def send(self, data: bytes) -> bytes:
        """Feed bytes; return everything the controller wrote in response."""
        self.controller.receive(data)
        return self.controller.read_output()

    def tick(self, count: int = 1) -> bytes:
        """Advance the clock one period and tick, ``count`` times; return the output."""
        for _ in range(count):
            self.clock.time_s = round(self.clock.time_s + TICK_S, 9)
            self.controller.tick()
        return self.controller.read_output()

    def run(self, seconds: float) -> bytes:
        return self.tick(round(seconds / TICK_S))

    def set_depth_cm(self, depth_cm: int) -> None:
        """Make the pressure sensor read ``depth_cm`` under the default calibration."""
        assert depth_cm % 2 == 0, "the default calibration has 2 cm steps"
        self.pressure.raw = 20 + depth_cm // 2

    @property
    def vertical_duties(self) -> tuple[int, int]:
        return self.thrusters.duties[4], self.thrusters.duties[5]

    @property
    def horizontal_duties(self) -> tuple[int, ...]:
        return self.thrusters.duties[:4]


def make_rig(config: ControllerConfig | None = None, **changes: Any) -> Rig:
    """A rig with the default configuration, or ``config`` with ``changes`` applied."""
    config = replace(config or ControllerConfig(), **changes)
    clock = FakeClock()
    thrusters = FakeThrusters()
    pressure = FakePressure()
    imu = FakeImu()
    leak = FakeLeak()
    claw = FakeClaw(clock)
    hardware = Hardware(thrusters, pressure, imu, leak, claw, clock)
    controller = Controller(config, hardware)
    return Rig(controller, clock, thrusters, pressure, imu, leak, claw)
