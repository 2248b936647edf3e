"""The depth PID (P10): thrust from depth error, with anti-windup and derivative on measurement."""

from __future__ import annotations

from rovlink.controller.config import DepthPidConfig

__all__ = ["DepthPid"]

_OUTPUT_LIMIT_PERCENT = 100.0


class DepthPid:
    """Vertical thrust in % (+ up) that holds a target depth.

    * The gains are the protocol's integers 0–99 times the configured scales.
    * Derivative on measurement: the D term acts on the filtered vertical speed, not on the
      error, so a new target causes no kick.
    * Anti-windup: the integral stops growing while the output is saturated in the direction
      the error pushes it, and is itself held within the output range.
    * The caller may narrow the output range (``lower``/``upper``), e.g. to refuse down thrust
      below the maximum depth; the anti-windup follows the narrowed range.
    """

    __slots__ = (
        "_config",
        "_filter_s",
        "_integral_percent",
        "_kd",
        "_ki",
        "_kp",
        "_last_depth_cm",
        "_speed_cm_s",
        "kd",
        "ki",
        "kp",
    )

    def __init__(self, config: DepthPidConfig) -> None:
        self._config = config
        self._filter_s = config.derivative_filter_s
        self.kp = config.kp
        self.ki = config.ki
        self.kd = config.kd
        self._kp = self._ki = self._kd = 0.0
        self.set_gains(config.kp, config.ki, config.kd)
        self._integral_percent = 0.0
        self._last_depth_cm: float | None = None
        self._speed_cm_s = 0.0

    def set_gains(self, kp: int, ki: int, kd: int) -> None:
        """Set the integer gains (0–99) and derive the physical ones from the scales."""
        self.kp, self.ki, self.kd = kp, ki, kd
        self._kp = kp * self._config.kp_scale
        self._ki = ki * self._config.ki_scale
        self._kd = kd * self._config.kd_scale

    @property
    def integral_percent(self) -> float:
        """The integral term, % thrust: what holds the vehicle against its buoyancy."""
        return self._integral_percent

    @property
    def speed_cm_s(self) -> float:
        """The filtered vertical speed the D term uses, cm/s (+ descending)."""
        return self._speed_cm_s

    def reset(self) -> None:
        """Forget the integral and the speed estimate (on start, stop and mode changes)."""
        self._integral_percent = 0.0
        self._last_depth_cm = None
        self._speed_cm_s = 0.0

    def update(
        self,
        target_cm: float,
        depth_cm: float,
        dt_s: float,
        lower: float = -_OUTPUT_LIMIT_PERCENT,
        upper: float = _OUTPUT_LIMIT_PERCENT,
    ) -> float:
        """One control step: the thrust in [lower, upper] % for the measured ``depth_cm``."""
        # Written with plain comparisons, not min/max: it runs every tick of a fast simulation.
        error_cm = depth_cm - target_cm  # too deep → positive → thrust up
        last = self._last_depth_cm
        self._last_depth_cm = depth_cm
        speed = self._speed_cm_s
        previous = integral = self._integral_percent
        if dt_s > 0.0:
            if last is not None:
                # Depth arrives in whole centimetres: the filter keeps a one-count step from
                # kicking the thrusters.
                raw_speed = (depth_cm - last) / dt_s
                speed += (raw_speed - speed) * dt_s / (self._filter_s + dt_s)
                self._speed_cm_s = speed
            integral += self._ki * error_cm * dt_s
        proportional_derivative = self._kp * error_cm + self._kd * speed
        output = proportional_derivative + integral
        # Conditional integration: no integrating further into a saturated output.
        if (output > upper and error_cm > 0) or (output < lower and error_cm < 0):
            integral = previous
        if integral > upper:
            integral = upper
        elif integral < lower:
            integral = lower
        self._integral_percent = integral
        output = proportional_derivative + integral
        if output > upper:
            return upper
        if output < lower:
            return lower
        return output
