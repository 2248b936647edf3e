"""Simulated devices: the hardware-abstraction layer of :mod:`rovlink.controller.hardware`.

Sensors read the vehicle's true state and add noise and quantisation, as the real parts do.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass, field, fields

from rovlink.controller import Attitude
from rovlink.controller.config import parameter_doc as _doc
from rovlink.sim.vehicle import Vehicle

__all__ = [
    "SensorParams",
    "SimClaw",
    "SimClock",
    "SimImu",
    "SimLeakSensor",
    "SimPressureSensor",
    "SimThrusters",
]

_ADC_MAX = 1023  # 10-bit converter


@dataclass(frozen=True, slots=True)
class SensorParams:
    """Sensor characteristics; the defaults match the controller's default `sdz`/`sdk`."""

    pressure_zero_raw: float = field(
        default=20.0, metadata=_doc("ADC reading at the surface, counts")
    )
    pressure_counts_per_m: float = field(
        default=50.0,
        metadata=_doc("ADC counts per metre of water (50: 2 cm a count, 0–20 m over 10 bits)"),
    )
    pressure_noise_counts: float = field(
        default=0.2,
        metadata=_doc(
            "pressure noise before quantisation, rms counts (triangular, so at most 2.45 × rms: "
            "0.2 keeps every reading within one count of the truth)"
        ),
    )
    attitude_noise_deg: float = field(
        default=0.3, metadata=_doc("roll and pitch noise, rms degrees")
    )
    heading_noise_deg: float = field(default=0.5, metadata=_doc("compass noise, rms degrees"))
    claw_travel_s: float = field(
        default=2.0, metadata=_doc("time for the claw to go from closed to fully open, s")
    )

    def __post_init__(self) -> None:
        for item in fields(self):
            value = getattr(self, item.name)
            if not math.isfinite(value):
                raise ValueError(f"{item.name} must be a finite number, got {value}")
        for name in ("pressure_noise_counts", "attitude_noise_deg", "heading_noise_deg"):
            value = getattr(self, name)
            if value < 0:
                raise ValueError(f"{name} must be ≥ 0, got {value}")
        if not self.pressure_counts_per_m > 0:
            raise ValueError(f"pressure_counts_per_m must be > 0, got {self.pressure_counts_per_m}")
        if not self.claw_travel_s > 0:
            raise ValueError(f"claw_travel_s must be > 0, got {self.claw_travel_s}")


class SimClock:
    """Simulated time: advanced in whole ticks by the simulation, read by the controller."""

    __slots__ = ("_tick_s", "ticks")

    def __init__(self, tick_s: float) -> None:
        self._tick_s = tick_s
        self.ticks = 0

    def now_s(self) -> float:
        """Seconds since the simulation started (a whole number of ticks: no drift)."""
        return self.ticks * self._tick_s


class SimThrusters:
    """Thruster outputs that drive the vehicle model."""

    __slots__ = ("_vehicle",)

    def __init__(self, vehicle: Vehicle) -> None:
        self._vehicle = vehicle

    def set_duties(self, duties: Sequence[int]) -> None:
        """Apply signed duties to the vehicle's thrusters."""
        self._vehicle.set_duties(duties)


class SimPressureSensor:
    """An analog pressure sensor on a 10-bit ADC: linear in depth, noisy, quantised, clipped.

    Every conversion has its own noise. The first one in each tick of ``clock`` (the control
    loop's) draws it from ``rng``, any further one in the same tick (a host's query) from
    ``extra_rng``: so the loop's readings, and the motion they steer, are the same however
    often a host queries.
    """

    __slots__ = (
        "_clock",
        "_extra_random",
        "_noise_scale",
        "_per_m",
        "_random",
        "_tick",
        "_vehicle",
        "_zero",
    )

    def __init__(
        self,
        vehicle: Vehicle,
        params: SensorParams,
        rng: random.Random,
        *,
        clock: SimClock,
        extra_rng: random.Random,
    ) -> None:
        self._vehicle = vehicle
        self._zero = params.pressure_zero_raw
        self._per_m = params.pressure_counts_per_m
        # Triangular noise (the sum of two uniforms, variance 1/6) with the configured rms: close
        # enough to Gaussian for an ADC's noise, and cheap enough for a fast simulation.
        self._noise_scale = params.pressure_noise_counts * math.sqrt(6.0)
        self._random = rng.random
        self._extra_random = extra_rng.random
        self._clock = clock
        self._tick = 0  # the tick of the last first conversion; before the first tick, none

    def read_raw(self) -> int:
        """One conversion, 0–1023."""
        ticks = self._clock.ticks
        if ticks != self._tick:
            self._tick = ticks
            random = self._random
        else:
            random = self._extra_random
        noise = (random() + random() - 1.0) * self._noise_scale
        counts = self._zero + self._vehicle.depth_m * self._per_m + noise
        raw = math.floor(counts + 0.5)
        return 0 if raw < 0 else min(raw, _ADC_MAX)


class SimImu:
    """Roll, pitch and compass heading with noise; heading wraps into 0–360."""

    __slots__ = ("_params", "_rng", "_vehicle")

    def __init__(self, vehicle: Vehicle, params: SensorParams, rng: random.Random) -> None:
        self._vehicle = vehicle
        self._params = params
        self._rng = rng

    def read_attitude(self) -> Attitude:
        """The current attitude as the IMU measures it."""
        roll_deg, pitch_deg = self._vehicle.roll_pitch_deg()
        gauss = self._rng.gauss
        params = self._params
        return Attitude(
            roll_deg + gauss(0.0, params.attitude_noise_deg),
            pitch_deg + gauss(0.0, params.attitude_noise_deg),
            (self._vehicle.heading_deg + gauss(0.0, params.heading_noise_deg)) % 360.0,
        )


class SimLeakSensor:
    """A leak detector with a hardware latch: scheduled wet intervals, however short, are seen."""

    __slots__ = ("_clock", "_last_read_s", "_wet_intervals")

    def __init__(self, clock: SimClock) -> None:
        self._clock = clock
        self._wet_intervals: list[tuple[float, float]] = []
        self._last_read_s = -math.inf

    def add_wet_interval(self, start_s: float, duration_s: float) -> None:
        """The probe is wet from ``start_s`` for ``duration_s`` seconds (``inf``: for good)."""
        self._wet_intervals.append((start_s, start_s + duration_s))

    def fired_since_last_read(self) -> bool:
        """Whether the probe was wet at any moment since the previous read."""
        intervals = self._wet_intervals
        if not intervals:
            return False
        now = self._clock.now_s()
        since = self._last_read_s
        self._last_read_s = now
        fired = any(start <= now and end > since for start, end in intervals)
        self._wet_intervals = [(start, end) for start, end in intervals if end > now]
        return fired


class SimClaw:
    """The claw motor: records its drive history and the claw's opening."""

    __slots__ = ("_changed_s", "_clock", "_opening", "_travel_s", "direction", "history")

    def __init__(self, clock: SimClock, params: SensorParams) -> None:
        self._clock = clock
        self._travel_s = params.claw_travel_s
        self._opening = 0.0
        self._changed_s = 0.0
        self.direction = 0
        #: (time_s, direction) for every change of drive.
        self.history: list[tuple[float, int]] = []

    def drive(self, direction: int) -> None:
        """Run the motor: +1 opens, −1 closes, 0 stops."""
        if direction == self.direction:
            return
        self._opening = self.opening
        self._changed_s = self._clock.now_s()
        self.direction = direction
        self.history.append((self._changed_s, direction))

    @property
    def opening(self) -> float:
        """How far open the claw is, 0 (closed) to 1 (open)."""
        elapsed = self._clock.now_s() - self._changed_s
        opening = self._opening + self.direction * elapsed / self._travel_s
        return min(max(opening, 0.0), 1.0)
