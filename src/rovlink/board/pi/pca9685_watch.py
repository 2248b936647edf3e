"""The PCA9685 read back at a bounded rate, and started again at neutral when it has reset.

A supply dip (thrusters starting on a sagging battery) can reset the PCA9685 without the Pi
noticing: it comes back as after power-on, asleep with every output off, so the ESCs lose their
pulses and stop, while every later write is still acknowledged and the controller believes it
is driving. Only reading the chip's registers back shows it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from rovlink.board.pi.pca9685 import Pca9685

__all__ = ["Pca9685ResetWatch"]


class Pca9685ResetWatch:
    """Every ``interval_s``: read MODE1 and PRE_SCALE back; if the chip was reset, start it
    again with the outputs at ``rest_pulses_us()`` (neutral) and say so.

    It never restores the last thrust: the board loop then stops and locks the controller, so
    the robot moves again only when a host sends `#start!` and a motion. ``resets`` counts the
    resets found (a reset that could not be repaired at once counts once, however often it is
    tried again).
    """

    def __init__(
        self,
        pca: Pca9685,
        rest_pulses_us: Callable[[], Mapping[int, float]],
        interval_s: float,
    ) -> None:
        if not (math.isfinite(interval_s) and interval_s > 0):
            raise ValueError(f"interval_s must be > 0, got {interval_s}")
        self.name = f"PWM board PCA9685 at {pca.address:#04x}"
        self.resets = 0
        self.interval_s = interval_s
        self._pca = pca
        self._rest_pulses_us = rest_pulses_us
        self._next_s = -math.inf
        self._repairing = False  # a reset found whose start failed: it is tried again

    def is_due(self, now_s: float) -> bool:
        """Whether ``interval_s`` has passed since the last check (the first is due at once)."""
        return now_s >= self._next_s

    def check(self, now_s: float) -> str | None:
        """Read the chip back; a description of a reset found (and the chip started again), or
        None. The next check is due ``interval_s`` later.

        Raises :class:`OSError` when the chip does not answer the read-back.
        """
        self._next_s = now_s + self.interval_s
        pca = self._pca
        found = pca.reset_found()
        if found is None:
            self._repairing = False
            return None
        if not self._repairing:
            self.resets += 1
        frequency_hz = pca.frequency_hz
        assert frequency_hz is not None  # reset_found() refuses a chip never started
        try:
            pca.start(frequency_hz, self._rest_pulses_us())
        except OSError as error:
            self._repairing = True
            return (
                f"{self.name} was reset ({found}); starting it again failed ({error}), "
                f"tried again in {self.interval_s:g} s"
            )
        self._repairing = False
        return f"{self.name} was reset ({found}); started again, outputs at neutral"
