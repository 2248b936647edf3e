"""The verification step: a depth step with the tuned gains, measured as the host sees it."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from rovlink.tuning.plant import Plant, TuneAbortedError
from rovlink.tuning.rules import ProtocolGains

__all__ = [
    "StepMetrics",
    "StepResult",
    "StepSettings",
    "centred_mean",
    "run_step",
    "step_metrics",
]


@dataclass(frozen=True)
class StepSettings:
    """The step: from ``from_cm`` (held ``hold_s`` first) to ``to_cm``, watched ``watch_s``."""

    from_cm: int = 0
    to_cm: int = 100
    #: Long enough for the integral to find the trim at ``from_cm`` after the move there: the
    #: step is then one from a held depth, not the tail of the move (with 10 s and an integral
    #: time of 19 s, the move's windup was still decaying when the step began).
    hold_s: float = 30.0
    watch_s: float = 70.0
    sample_s: float = 0.05
    band_cm: float = 3.0
    settle_by_s: float = 10.0
    #: The measured depth is judged as its mean over this window, centred on each reading:
    #: ``qd`` comes in the sensor's counts (2 cm at the default calibration) with up to a count
    #: of noise, so single readings of a vehicle 2.5 cm off read 4 cm off, and the extreme of
    #: a minute of readings said more of the sensor than of the vehicle. The window is short
    #: against the loop's response and a wave (a 5 s wave loses under 2 % of its height).
    smooth_s: float = 0.5


@dataclass(frozen=True)
class StepMetrics:
    """Overshoot, settling time and RMS error of a step response."""

    overshoot_cm: float
    settling_s: float
    rms_cm: float


def step_metrics(
    times_s: Sequence[float], depths_cm: Sequence[float], settings: StepSettings
) -> StepMetrics:
    """The metrics of a recorded step: overshoot past the target, the time from which the depth
    stays within ``band_cm``, and the RMS error from ``settle_by_s`` to the end."""
    direction = 1 if settings.to_cm >= settings.from_cm else -1
    overshoot = max(0.0, *(direction * (depth - settings.to_cm) for depth in depths_cm))
    settling = 0.0
    squares = []
    for time_s, depth in zip(times_s, depths_cm, strict=True):
        error = depth - settings.to_cm
        if abs(error) > settings.band_cm:
            settling = time_s
        if time_s >= settings.settle_by_s:
            squares.append(error * error)
    rms = math.sqrt(sum(squares) / len(squares)) if squares else math.nan
    return StepMetrics(float(overshoot), settling, rms)


def centred_mean(times_s: Sequence[float], values: Sequence[float], window_s: float) -> list[float]:
    """Each value replaced by the mean of the values whose times lie within ``window_s / 2`` of
    its own (fewer at the ends); ``times_s`` ascending. A window of 0 leaves the values as
    they are.

    >>> centred_mean([0.0, 1.0, 2.0, 3.0], [0, 2, 4, 0], 2.0)
    [1.0, 2.0, 2.0, 2.0]
    """
    half_s = window_s / 2.0
    sums = [0.0]
    for value in values:
        sums.append(sums[-1] + value)
    means = []
    first = last = 0  # the window is values[first:last]
    for time_s in times_s:
        while times_s[first] < time_s - half_s:
            first += 1
        while last < len(times_s) and times_s[last] <= time_s + half_s:
            last += 1
        means.append((sums[last] - sums[first]) / (last - first))
    return means


@dataclass
class StepResult:
    """The recorded step: the depth as the host measured it (``qd``) and, when the plant can
    tell (a simulation), the true depth."""

    settings: StepSettings
    times_s: list[float] = field(default_factory=list)
    depths_cm: list[int] = field(default_factory=list)
    true_depths_cm: list[float] = field(default_factory=list)

    @property
    def smoothed_depths_cm(self) -> list[float]:
        """The measured depth as the verification judges it: each reading replaced by the mean
        of the readings within ``smooth_s`` centred on it."""
        return centred_mean(self.times_s, self.depths_cm, self.settings.smooth_s)

    @property
    def measured(self) -> StepMetrics:
        """The metrics of the measured depth (:attr:`smoothed_depths_cm`)."""
        return step_metrics(self.times_s, self.smoothed_depths_cm, self.settings)

    @property
    def true(self) -> StepMetrics | None:
        """The metrics of the true depth, if known."""
        if not self.true_depths_cm:
            return None
        return step_metrics(self.times_s, self.true_depths_cm, self.settings)


def run_step(plant: Plant, gains: ProtocolGains, settings: StepSettings) -> StepResult:
    """Hold ``from_cm`` in depth mode with ``gains``, step to ``to_cm`` and record the depth.

    A step from the surface (``from_cm`` 0) starts with the PID afresh, as a dive from the
    surface does: floating there, the error is 0 and the integral keeps what it gathered on the
    way up, the opposite of the trim the step needs (see :func:`_start_afresh`).

    Both depth limits hold throughout, as in the relay once it has reached its target: untried
    gains that overshoot past one abort the verification with ``#stop!``, its message saying
    that the verification was under way.
    """
    client = plant.client
    try:
        plant.send(lambda: client.set_direct_mode(False))
        plant.send(lambda: client.set_depth_pid(gains.kp, gains.ki, gains.kd))
        plant.send(lambda: client.hold_depth(settings.from_cm))
        _watch(plant, settings.hold_s, settings.sample_s)
        if settings.from_cm == 0:
            _start_afresh(plant)
        plant.send(lambda: client.hold_depth(settings.to_cm))
        result = StepResult(settings)
        start_s = plant.now_s()
        while True:
            elapsed = plant.now_s() - start_s
            if elapsed > settings.watch_s:
                return result
            result.times_s.append(elapsed)
            result.depths_cm.append(plant.sample())
            truth = plant.true_depth_cm()
            if truth is not None:
                result.true_depths_cm.append(truth)
            plant.wait(settings.sample_s)
    except TuneAbortedError as error:
        raise TuneAbortedError(
            f"verification (gains {gains.kp} {gains.ki} {gains.kd}, {settings.from_cm} -> "
            f"{settings.to_cm} cm): {error}"
        ) from None


def _start_afresh(plant: Plant) -> None:
    """Leave depth mode and enter it again: the controller starts its PID afresh (P9; the
    reference controllers clear the integral on entering depth mode) and holds the depth now.

    At the surface the vehicle floats, the error is 0 and the integral cannot change: it keeps
    what it gathered as the vehicle rose to the surface, thrust up where the step down needs the
    trim, thrust down. The step then took 17–45 s to settle on the simulated vehicles, as any
    step from a depth hold at the surface would; the verification is of the gains, and a dive
    from the surface starts in depth mode with the integral empty.
    """
    client = plant.client
    plant.send(lambda: client.set_direct_mode(True))  # vertical thrust 0: it floats anyway
    plant.send(lambda: client.set_direct_mode(False))


def _watch(plant: Plant, seconds: float, sample_s: float) -> None:
    end_s = plant.now_s() + seconds
    while plant.now_s() < end_s:
        plant.sample()
        plant.wait(sample_s)
