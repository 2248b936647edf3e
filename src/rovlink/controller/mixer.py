"""The thruster mixer (P8, P11): set-points to signed PWM duties for the configured layout."""

from __future__ import annotations

import math
from collections.abc import Sequence

from rovlink.controller.config import ThrusterSpec

__all__ = ["ThrusterMixer", "duty"]

# Fractions come out of trigonometry: ignore float noise at a half-way point of rounding, so that
# thrusters meant to be equal get equal duties.
_ROUNDING_SLACK = 1e-9


def duty(fraction: float, max_pwm: int) -> int:
    """The signed PWM duty for a thrust fraction −1…+1 (P8), rounded half away from zero.

    >>> duty(0.5, 255), duty(-0.5, 255), duty(1.0, 200)
    (128, -128, 200)
    """
    value = fraction * max_pwm
    if value >= 0.0:
        return int(value + 0.5 + _ROUNDING_SLACK)
    return -int(0.5 + _ROUNDING_SLACK - value)


class ThrusterMixer:
    """Maps horizontal motion (direction, power) and vertical thrust to one duty per thruster.

    Horizontal: each thruster gets the projection of the wanted direction on its own axis; the
    projections are normalised so the largest is 100 % at full power, then scaled by power and
    by ``max_pwm``. A symmetric layout (such as the default vectored frame) thus moves without
    turning. Vertical thrusters all get the vertical thrust, scaled by ``max_pwm``.
    """

    __slots__ = (
        "_count",
        "_horizontal",
        "_horizontal_duties",
        "_horizontal_fractions",
        "_max_pwm",
        "_vertical_indices",
    )

    def __init__(self, thrusters: Sequence[ThrusterSpec], max_pwm: int) -> None:
        self._horizontal = [
            (index, math.radians(spec.angle_deg))
            for index, spec in enumerate(thrusters)
            if not spec.vertical
        ]
        self._vertical_indices = tuple(
            index for index, spec in enumerate(thrusters) if spec.vertical
        )
        self._horizontal_fractions = [0.0] * len(thrusters)
        self._count = len(thrusters)
        self._horizontal_duties = [0] * self._count
        self._max_pwm = max_pwm

    @property
    def max_pwm(self) -> int:
        """The duty cap (``mgmp``, 0–255): duty = |thrust fraction| × max_pwm (P8)."""
        return self._max_pwm

    @max_pwm.setter
    def max_pwm(self, max_pwm: int) -> None:
        self._max_pwm = max_pwm
        self._update_horizontal_duties()

    @property
    def thruster_count(self) -> int:
        """How many outputs the layout has."""
        return self._count

    def set_horizontal(self, direction_deg: float, power_percent: float) -> None:
        """Set horizontal motion: degrees clockwise from the bow, power 0–100 %."""
        fractions = [0.0] * self._count
        if power_percent > 0 and self._horizontal:
            heading = math.radians(direction_deg)
            projections = [(index, math.cos(heading - axis)) for index, axis in self._horizontal]
            largest = max(abs(value) for _, value in projections)
            if largest > 1e-9:
                scale = power_percent / 100.0 / largest
                for index, value in projections:
                    fractions[index] = value * scale
        self._horizontal_fractions = fractions
        self._update_horizontal_duties()

    def _update_horizontal_duties(self) -> None:
        # Cached: horizontal set-points change rarely, the vertical thrust every tick.
        max_pwm = self._max_pwm
        self._horizontal_duties = [duty(value, max_pwm) for value in self._horizontal_fractions]

    def horizontal_fractions(self) -> list[float]:
        """The horizontal thrust fraction (−1…+1) of every output, 0 for vertical thrusters."""
        return list(self._horizontal_fractions)

    def duties(self, vertical_percent: float) -> list[int]:
        """Every output's duty, with ``vertical_percent`` (−100…+100, + up) of vertical thrust."""
        duties = self._horizontal_duties.copy()
        vertical = duty(vertical_percent / 100.0, self._max_pwm)
        for index in self._vertical_indices:
            duties[index] = vertical
        return duties
