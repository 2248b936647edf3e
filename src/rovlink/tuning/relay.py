"""The relay experiment (Åström–Hägglund) in direct mode: the ultimate gain and period.

The host drives vertical thrust as a relay with hysteresis around the target depth: full
relay amplitude up while the vehicle is deeper than the target plus the hysteresis, down while
it is shallower than the target minus it. The loop settles into a limit cycle whose amplitude
``a`` and period give the ultimate gain ``Ku = 4 h / (π √(a² − ε²))`` and the ultimate period
``Tu``. A buoyant vehicle spends longer diving than rising; the relay's bias is moved each cycle
until both halves last as long (the thrust that holds the vehicle still, its trim).
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass, field

from rovlink.tuning.plant import Plant

__all__ = ["RelayResult", "RelaySettings", "run_relay"]


@dataclass(frozen=True)
class RelaySettings:
    """How the relay runs."""

    target_cm: int = 100
    amplitude_percent: int = 30
    hysteresis_cm: int = 3
    sample_s: float = 0.05
    warmup_cycles: int = 2
    measured_cycles: int = 4
    timeout_s: float = 120.0
    #: On the way down to the target, the depth read must get deeper (by a count or more)
    #: within this long, and in the relay move by a count: a depth sensor that is dead, stuck or
    #: reads backwards would let the relay drive the vehicle unchecked until ``timeout_s``. The
    #: simulated vehicles that dive at all go deeper every 2.6 s at most, and move in the relay
    #: every 1.5 s.
    stall_s: float = 10.0


@dataclass
class RelayResult:
    """The limit cycle and what it says about the plant."""

    ultimate_gain: float  # % thrust per cm
    ultimate_period_s: float
    amplitude_cm: float
    bias_percent: float
    times_s: list[float] = field(default_factory=list)
    depths_cm: list[int] = field(default_factory=list)
    outputs_percent: list[int] = field(default_factory=list)


def run_relay(plant: Plant, settings: RelaySettings) -> RelayResult:
    """Run the experiment (the robot unlocked, in direct mode) and measure the limit cycle."""
    h = settings.amplitude_percent
    epsilon = settings.hysteresis_cm
    target = settings.target_cm
    bias = 0.0
    up = False  # start by diving toward the target
    output = _clamp(round(bias - h))
    plant.vertical_thrust(output)
    start_s = plant.now_s()
    switch_times: list[float] = []  # the moments the relay switched up
    cycle_extremes: list[tuple[float, float]] = []
    phase_start_s = start_s
    up_s = down_s = 0.0
    low = high = None
    result = RelayResult(0.0, 0.0, 0.0, 0.0)
    first: tuple[int, int | None] | None = None  # the depth and raw pressure at the start
    # The depth read when it last got deeper (on the way down to the target) or moved (in the
    # relay, which keeps the vehicle moving: it stays within a count for 1.5 s at most on the
    # simulated vehicles), and when.
    moved: tuple[int, float] | None = None
    while True:
        now = plant.now_s()
        if now - start_s > settings.timeout_s:
            plant.abort(_no_oscillation(settings, bool(switch_times), high))
        # The shallow limit holds once the vehicle has been down to the target.
        depth = plant.sample(enforce_min=bool(switch_times))
        first = first or (depth, plant.last_pressure_raw)
        _check_depth_follows_pressure(plant, first, depth)
        # (up as well as down, once in the relay: on the way down, a vehicle at rest on a
        # bottom reads one count or the next)
        change = depth - moved[0] if moved is not None else _DEPTH_CHANGE_CM
        if change >= _DEPTH_CHANGE_CM or (switch_times and -change >= _DEPTH_CHANGE_CM):
            moved = (depth, now)
        elif moved is not None and now - moved[1] > settings.stall_s:
            plant.abort(_stalled(settings, bool(switch_times), moved[0], plant.last_pressure_raw))
        result.times_s.append(now - start_s)
        result.depths_cm.append(depth)
        result.outputs_percent.append(output)
        low = depth if low is None else min(low, depth)
        high = depth if high is None else max(high, depth)
        if not up and depth > target + epsilon:
            down_s = now - phase_start_s
            up, phase_start_s = True, now
            if switch_times:
                cycle_extremes.append((low, high))
                # Balance the halves: a longer dive than rise needs more down bias. Held within
                # ±h, so that the thrust stays within ±2h, as the command's prompt says (a hull
                # whose trim is past h does not dive to the target at all).
                bias += h * (up_s - down_s) / (up_s + down_s) * 0.5
                bias = max(-h, min(h, bias))
            low = high = depth
            switch_times.append(now)
        elif up and depth < target - epsilon:
            up_s = now - phase_start_s
            up, phase_start_s = False, now
        new_output = _clamp(round(bias + h if up else bias - h))
        if new_output != output:
            output = new_output
            plant.vertical_thrust(output)
        cycles = len(switch_times) - 1
        if cycles >= settings.warmup_cycles + settings.measured_cycles:
            break
        plant.wait(settings.sample_s)
    measured = settings.measured_cycles
    periods = [
        b - a
        for a, b in zip(switch_times[-measured - 1 : -1], switch_times[-measured:], strict=True)
    ]
    if max(periods) > _STEADY_RATIO * min(periods):
        # Noise, not the vehicle, switched the relay: the cycles are short and uneven, and the
        # gains from them nonsense (0 0 0 with 3 counts of noise in the simulated sensor). A
        # lost #mvs! leaves the thrust before it for a half cycle (3.6 to 8.8 s at a bit error
        # rate of 3e-4).
        spread = f"{min(periods):.2f} to {max(periods):.2f} s"
        plant.abort(
            f"the relay's cycles are not steady (the last {measured} lasted {spread}): a depth "
            f"reading noisier than the hysteresis ({epsilon} cm) switches the relay on noise "
            "(raise --hysteresis), and a link that loses frames loses the relay's thrust "
            "commands (see the link's counters)"
        )
    amplitudes = [(hi - lo) / 2.0 for lo, hi in cycle_extremes[-measured:]]
    amplitude = statistics.mean(amplitudes)
    effective = math.sqrt(max(amplitude**2 - epsilon**2, (amplitude / 4.0) ** 2))
    result.ultimate_gain = 4.0 * h / (math.pi * effective)
    result.ultimate_period_s = statistics.mean(periods)
    result.amplitude_cm = amplitude
    result.bias_percent = bias
    return result


#: The longest of the measured cycles may last at most this many times the shortest: on the
#: simulated vehicles, waves and all, they are within 1.25 times; with a depth reading noisier
#: than the hysteresis, 2 to 100 times.
_STEADY_RATIO = 2.0

#: A rise of the raw pressure (counts) that must show in the depth: 50 cm at the default
#: calibration (2 cm a count). Well above what a vehicle floating at the surface, its depth
#: clamped at 0 while the raw reading is below the zero, sees of waves and noise.
_RAW_RISE_COUNTS = 25
#: The least the depth must have changed by then, cm.
_DEPTH_CHANGE_CM = 2


def _check_depth_follows_pressure(
    plant: Plant, first: tuple[int, int | None], depth_cm: int
) -> None:
    """Abort when the pressure has risen but the depth has not: the depth limits are judged on
    the depth (qd), so a calibration that does not follow the pressure (``sdk`` left at 1 by a
    check run, or 0) would let the relay drive the vehicle down unchecked."""
    first_depth, first_raw = first
    raw = plant.last_pressure_raw
    if first_raw is None or raw is None or raw - first_raw < _RAW_RISE_COUNTS:
        return
    if abs(depth_cm - first_depth) < _DEPTH_CHANGE_CM:
        plant.abort(
            f"the raw pressure rose from {first_raw} to {raw} but the depth stayed at "
            f"{depth_cm} cm: the depth calibration (sdz, sdk) does not follow the pressure, and "
            "the depth limits cannot be kept (rovlink check leaves sdk at a test value; "
            "calibrate with rovlink calibrate)"
        )


def _stalled(settings: RelaySettings, reached: bool, depth_cm: int, raw: int | None) -> str:
    """Why the relay stopped: the depth read got no deeper on the way down, or stopped moving
    in the relay, for ``stall_s``."""
    if reached:
        return (
            f"the depth read stayed within {_DEPTH_CHANGE_CM - 1} cm of {depth_cm} cm (raw "
            f"{raw}) for {settings.stall_s:g} s of the relay's thrust: a depth sensor that "
            "stopped would let the relay drive the vehicle unchecked past the limits"
        )
    return (
        f"the depth read got no deeper than {depth_cm} cm (raw {raw}) in "
        f"{settings.stall_s:g} s of {settings.amplitude_percent} % down thrust: a depth sensor "
        "that is dead or reads backwards would let the vehicle dive unchecked past the limits; "
        "or the vehicle cannot go deeper: is it in water deep enough, and is the PWM cap (mgmp) "
        "above 0? (rovlink check leaves it at 0)"
    )


def _no_oscillation(settings: RelaySettings, reached: bool, deepest_cm: int | None) -> str:
    """Why the relay timed out: no steady oscillation, or (the commonest cause) the vehicle
    never got down to the target, which the thrust alone cannot tell."""
    if reached:
        return f"no steady oscillation within {settings.timeout_s:g} s"
    deepest = "no depth read" if deepest_cm is None else f"the deepest was {deepest_cm} cm"
    return (
        f"the vehicle did not get below {settings.target_cm + settings.hysteresis_cm} cm in "
        f"{settings.timeout_s:g} s of {settings.amplitude_percent} % down thrust ({deepest}): "
        "is it in the water, and is the PWM cap (mgmp) above 0? (rovlink check leaves it at 0)"
    )


def _clamp(percent: int) -> int:
    return max(-100, min(100, percent))
