"""The vehicle as the tuner sees it: depth and leak in, vertical commands out, a clock, limits.

Every sample reads the depth and the leak latch and checks the safe limits; a leak, a depth
outside the limits, a lost link or a controller reset sends ``#stop!`` and raises
:class:`TuneAbortedError`, and so does a ``stop()`` from another thread that supersedes the
command the experiment was sending.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from rovlink.client import Client, ClientError, SupersededByStopError

__all__ = ["DepthLimits", "Plant", "TuneAbortedError"]


class TuneAbortedError(Exception):
    """The experiment stopped for safety, with ``#stop!``. The message says why, and whether
    the ``#stop!`` went (a link that is gone takes nothing)."""


@dataclass(frozen=True)
class DepthLimits:
    """The depths the vehicle must stay between during tuning, cm."""

    min_cm: int
    max_cm: int

    def __post_init__(self) -> None:
        if not 0 <= self.min_cm < self.max_cm:
            raise ValueError(
                f"depth limits must satisfy 0 ≤ min < max, got {self.min_cm}–{self.max_cm} cm"
            )


class Plant:
    """The robot through a client, sampled on ``clock`` and paced by ``sleep``.

    For a real robot both are the wall clock's; for a simulated robot stepped by hand they are
    the simulation's, so an experiment of minutes runs in seconds and reproduces exactly. A
    simulation can also give ``truth``, the true depth in cm, for the verification's figures.
    """

    def __init__(
        self,
        client: Client,
        limits: DepthLimits,
        *,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        truth: Callable[[], float] | None = None,
    ) -> None:
        self.client = client
        self.limits = limits
        self._clock = clock
        self._sleep = sleep
        self._truth = truth
        self._stop_outcome: str | None = None
        #: The raw pressure reading (qr) of the last sample, for checks of the depth's
        #: calibration; None before the first.
        self.last_pressure_raw: int | None = None
        # A reset the driver suspects from here on ends the experiment (P21: a controller that
        # reset is locked and drops the thrust the experiment sends, as the vehicle drifts).
        self._resets_before = client.counters.resets_suspected

    def now_s(self) -> float:
        """The plant's clock, s."""
        return self._clock()

    def true_depth_cm(self) -> float | None:
        """The true depth where the plant knows it (a simulation, through ``truth``), else None."""
        return self._truth() if self._truth is not None else None

    def wait(self, seconds: float) -> None:
        """Let ``seconds`` pass."""
        self._sleep(seconds)

    def sample(self, *, enforce_min: bool = True) -> int:
        """The depth, cm, after checking the leak latch and the limits."""
        try:
            sensors = self.client.sensors()
        except (ClientError, ConnectionError) as error:
            self.abort(f"the link failed: {error}")
        if self.client.counters.resets_suspected > self._resets_before:
            self.abort(
                "the controller reset (its replies stopped, P21): it is locked now, and the "
                "experiment cannot go on"
            )
        if sensors.leak_detected:
            self.abort("the leak sensor fired")
        self.last_pressure_raw = sensors.pressure_raw
        depth = sensors.depth_cm
        if depth > self.limits.max_cm:
            self.abort(f"depth {depth} cm is past the limit of {self.limits.max_cm} cm")
        if enforce_min and depth < self.limits.min_cm:
            self.abort(f"depth {depth} cm is above the limit of {self.limits.min_cm} cm")
        return depth

    def vertical_thrust(self, percent: int) -> None:
        """Direct-mode vertical thrust, % (+ up)."""
        self._guarded(lambda: self.client.set_vertical_thrust(percent))

    def send(self, action: Callable[[], None]) -> None:
        """Run a client call; a failure aborts."""
        self._guarded(action)

    def stop(self) -> str:
        """``#stop!``, at most once per experiment, whatever state the link is in; what became
        of it: ``#stop! sent``, or ``#stop! could not be sent: <why>`` (a link that is gone:
        the controller's link-loss watchdog stops the robot then)."""
        if self._stop_outcome is None:
            try:
                self.client.stop()
            except (ClientError, ConnectionError) as error:
                self._stop_outcome = f"#stop! could not be sent: {error}"
            else:
                self._stop_outcome = "#stop! sent"
        return self._stop_outcome

    def abort(self, why: str) -> None:
        """Stop the robot and raise :class:`TuneAbortedError` saying why, and whether the
        ``#stop!`` went."""
        outcome = self.stop()
        if why.startswith("the link failed") and outcome != "#stop! sent":
            outcome = "#stop! could not be sent"  # (the reason is the failure just named)
        raise TuneAbortedError(f"{why}: {outcome}")

    def _guarded(self, action: Callable[[], None]) -> None:
        try:
            action()
        except SupersededByStopError as error:
            # The program's own stop (a safety thread's): the experiment ends as asked, it is
            # not the link that failed.
            self.abort(f"stop() was called during the experiment ({error.command} not sent)")
        except (ClientError, ConnectionError) as error:
            self.abort(f"the link failed: {error}")
