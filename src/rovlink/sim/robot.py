"""A simulated robot: the controller on its simulated board, stepped in simulated time.

:class:`SimulatedRobot` is the one place where controller and physics advance together; the
in-process port (:func:`rovlink.sim.open_port`), the ``rovlink sim`` server and the benchmarks all
step it, in real time or as fast as the CPU allows, through the same :meth:`~SimulatedRobot.step`.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
from collections.abc import Callable, Hashable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rovlink.controller import ControllerConfig, Hardware, config_from_mapping
from rovlink.controller.config import (
    ConfigError,
    dataclass_from_table,
    read_toml,
    table_reference,
)
from rovlink.controller.controller import Controller
from rovlink.sim.devices import (
    SensorParams,
    SimClaw,
    SimClock,
    SimImu,
    SimLeakSensor,
    SimPressureSensor,
    SimThrusters,
)
from rovlink.sim.vehicle import Vehicle, VehicleParams

__all__ = [
    "DEFAULT_LEAK_PULSE_S",
    "SimConfig",
    "SimulatedRobot",
    "load_sim_config",
    "sim_config_from_mapping",
    "sim_config_reference",
]

#: The length of an injected leak pulse, s.
DEFAULT_LEAK_PULSE_S = 0.1


@dataclass(frozen=True, slots=True)
class SimConfig:
    """A simulated robot's configuration: its controller, vehicle and sensors."""

    controller: ControllerConfig = field(default_factory=ControllerConfig)
    vehicle: VehicleParams = field(default_factory=VehicleParams)
    sensors: SensorParams = field(default_factory=SensorParams)


def sim_config_from_mapping(data: Mapping[str, Any], source: str = "config") -> SimConfig:
    """The configuration in parsed TOML: controller tables plus ``[vehicle]`` and ``[sensors]``."""
    controller = config_from_mapping(data, source, other_tables=("vehicle", "sensors"))
    try:
        vehicle = dataclass_from_table(
            VehicleParams, data.get("vehicle", {}), f"{source} [vehicle]"
        )
        sensors = dataclass_from_table(SensorParams, data.get("sensors", {}), f"{source} [sensors]")
    except ValueError as error:
        raise ConfigError(str(error)) from None
    return SimConfig(controller, vehicle, sensors)


def load_sim_config(path: Path | str) -> SimConfig:
    """Read a simulated robot's TOML file (controller tables, ``[vehicle]``, ``[sensors]``)."""
    return sim_config_from_mapping(read_toml(path), str(path))


def sim_config_reference() -> str:
    """Markdown tables of the simulator's own tables, ``[vehicle]`` and ``[sensors]``."""
    vehicle = table_reference("[vehicle]", VehicleParams())
    return vehicle + "\n" + table_reference("[sensors]", SensorParams())


class SimulatedRobot:
    """The controller on a simulated board in a simulated vehicle.

    ``step()`` advances one control period: scheduled scenario events, then the physics over the
    period, then the controller's tick. Bytes from the host go to ``receive``; the controller's
    output goes to ``write`` (or, without it, to :meth:`Controller.read_output`), and what every
    line served must hear to ``write_to_every_line`` (see :class:`Controller`). With a ``seed``
    the run is reproducible: the same bytes at the same simulated times give the same results.
    """

    def __init__(
        self,
        config: SimConfig | None = None,
        *,
        seed: int | None = None,
        write: Callable[[bytes], None] | None = None,
        write_to_every_line: Callable[[bytes], None] | None = None,
    ) -> None:
        config = config if config is not None else SimConfig()
        self.config = config
        self.seed = seed if seed is not None else random.SystemRandom().randrange(2**32)
        seeds = random.Random(self.seed)
        # Separate streams: how often the host queries must not change the physics, nor what
        # the control loop reads. (Streams added later are drawn last, so that a seed keeps
        # giving the run it gave.)
        physics_rng = random.Random(seeds.getrandbits(64))
        loop_pressure_rng = random.Random(seeds.getrandbits(64))
        query_pressure_rng = random.Random(seeds.getrandbits(64))
        imu_rng = random.Random(seeds.getrandbits(64))
        self.tick_s = config.controller.tick_s
        self.clock = SimClock(self.tick_s)
        self.vehicle = Vehicle(config.vehicle, config.controller.thrusters, physics_rng)
        self.pressure = SimPressureSensor(
            self.vehicle,
            config.sensors,
            loop_pressure_rng,
            clock=self.clock,
            extra_rng=query_pressure_rng,
        )
        self.imu = SimImu(self.vehicle, config.sensors, imu_rng)
        self.leak = SimLeakSensor(self.clock)
        self.claw = SimClaw(self.clock, config.sensors)
        self.hardware = Hardware(
            thrusters=SimThrusters(self.vehicle),
            pressure=self.pressure,
            imu=self.imu,
            leak=self.leak,
            claw=self.claw,
            clock=self.clock,
        )
        self.controller = Controller(
            config.controller, self.hardware, write, write_to_every_line=write_to_every_line
        )
        self._events: list[tuple[float, int, Callable[[], None]]] = []
        self._event_order = itertools.count()

    @property
    def time_s(self) -> float:
        """Simulated seconds since the start."""
        return self.clock.now_s()

    def receive(self, data: bytes, line: Hashable = None) -> None:
        """Bytes from the host on ``line`` (see :meth:`Controller.receive`), handled at the
        current simulated time."""
        self.controller.receive(data, line)

    def step(self) -> None:
        """Advance one control period."""
        clock = self.clock
        events = self._events
        if events and events[0][0] <= clock.ticks * self.tick_s:
            self._run_due_events()
        self.vehicle.step(self.tick_s)
        clock.ticks += 1
        self.controller.tick()

    def advance(self, seconds: float) -> None:
        """Advance by ``seconds`` of simulated time (rounded to whole ticks)."""
        step = self.step
        for _ in range(round(seconds / self.tick_s)):
            step()

    def run_until(self, time_s: float) -> None:
        """Advance until the simulated time is at least ``time_s``."""
        target = math.ceil(time_s / self.tick_s - 1e-9)
        step = self.step
        while self.clock.ticks < target:
            step()

    # -- scenario hooks ----------------------------------------------------------------------

    # The hooks refuse NaN and infinity at the call: in the physics they ended the simulation
    # at its next sensor reading (a NaN depth) with a traceback far from the cause, and a NaN
    # time sat at the top of the event queue, so no later event ever ran.

    def schedule(self, at_s: float, action: Callable[[], None]) -> None:
        """Run ``action`` at simulated time ``at_s`` (at once, on the next step, if it is past)."""
        _require_finite("at_s", at_s)
        heapq.heappush(self._events, (at_s, next(self._event_order), action))

    def inject_leak(
        self, at_s: float | None = None, duration_s: float = DEFAULT_LEAK_PULSE_S
    ) -> None:
        """Wet the leak probe for ``duration_s`` (``math.inf``: for good) from ``at_s``
        (default: now)."""
        if at_s is not None:
            _require_finite("at_s", at_s)
        if not duration_s >= 0:  # (NaN too)
            raise ValueError(f"duration_s must be ≥ 0, got {duration_s}")
        start_s = self.time_s if at_s is None else at_s
        self.leak.add_wet_interval(start_s, duration_s)

    def set_net_buoyancy(self, net_buoyancy_n: float) -> None:
        """Change buoyancy minus weight, N (e.g. after picking up a load)."""
        _require_finite("net_buoyancy_n", net_buoyancy_n)
        self.vehicle.net_buoyancy_n = net_buoyancy_n

    def set_current(self, speed_m_s: float, toward_deg: float) -> None:
        """A water current of ``speed_m_s`` flowing toward ``toward_deg`` (clockwise from north)."""
        _require_finite("speed_m_s", speed_m_s)
        _require_finite("toward_deg", toward_deg)
        angle = math.radians(toward_deg)
        self.vehicle.current_north_m_s = speed_m_s * math.cos(angle)
        self.vehicle.current_east_m_s = speed_m_s * math.sin(angle)

    def _run_due_events(self) -> None:
        now = self.time_s
        events = self._events
        while events and events[0][0] <= now:
            _, _, action = heapq.heappop(events)
            action()


def _require_finite(name: str, value: float) -> None:
    if not math.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value}")
