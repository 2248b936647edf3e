"""Two-point depth calibration (P13): the raw pressure at the surface and at a known depth give
the depth zero (``sdz``) and coefficient (``sdk``).

depth_cm = (raw − zero) · k / 100, so zero = raw at the surface and
k = depth_cm · 100 / (raw_at_depth − raw_at_surface), rounded, within the command table's ranges.

>>> two_point(20.0, 70.0, 100).zero_raw, two_point(20.0, 70.0, 100).k
(20, 200)
"""

from __future__ import annotations

from dataclasses import dataclass

from rovlink.protocol import Kind, lookup

__all__ = ["DEFAULT_MIN_COUNTS", "Calibration", "CalibrationError", "two_point"]

#: The deepest depth the controller reports, cm: deeper reads as this (P13).
_MAX_DEPTH_CM = lookup("qd", Kind.RESPONSE).arguments[0].maximum

#: The two readings must be at least this many counts apart: closer, one count of noise moves k
#: by more than 10 %.
DEFAULT_MIN_COUNTS = 10


class CalibrationError(ValueError):
    """The two points cannot give a calibration; the message says why."""


@dataclass(frozen=True)
class Calibration:
    """The values for ``#sdz!`` and ``#sdk!``, and what they mean."""

    zero_raw: int
    k: int
    surface_raw: float
    depth_raw: float
    depth_cm: int

    @property
    def cm_per_count(self) -> float:
        """The depth resolution the calibration gives, cm per raw count."""
        return self.k / 100.0

    def depth_for(self, raw: float) -> int:
        """The depth the controller will report for ``raw`` (P13)."""
        return max(0, min(_MAX_DEPTH_CM, int((raw - self.zero_raw) * self.k // 100)))

    def shown_at(self, raw: float) -> bool:
        """Whether the depth read at ``raw`` can show that the controller took these values:
        not at an end of the depth range, where other values read the same (at or above the
        surface every calibration reads 0 cm).

        >>> calibration = two_point(20.0, 120.0, 200)
        >>> calibration.shown_at(20), calibration.shown_at(70)
        (False, True)
        """
        return 0 < self.depth_for(raw) < _MAX_DEPTH_CM


def two_point(
    surface_raw: float, depth_raw: float, depth_cm: int, min_counts: float = DEFAULT_MIN_COUNTS
) -> Calibration:
    """The calibration from two readings; :class:`CalibrationError` if they cannot give one."""
    zero_arg = lookup("sdz").arguments[0]
    k_arg = lookup("sdk").arguments[0]
    if depth_cm <= 0:
        raise CalibrationError(f"the known depth must be > 0 cm, got {depth_cm}")
    for name, raw in (("surface", surface_raw), ("depth", depth_raw)):
        if not zero_arg.minimum <= raw <= zero_arg.maximum:
            raise CalibrationError(
                f"the {name} reading {raw:g} is outside the sensor's range {zero_arg.range_text()}"
            )
    counts = depth_raw - surface_raw
    if counts < min_counts:
        raise CalibrationError(
            f"the readings are {counts:g} counts apart (surface {surface_raw:g}, at "
            f"{depth_cm} cm {depth_raw:g}); at least {min_counts:g} are needed: go deeper, "
            "or check that the sensor reads more with depth"
        )
    zero = round(surface_raw)
    # k over the counts from the zero the controller is given, not from the surface reading:
    # the line through (zero, 0 cm) then passes through the known depth, where a k from the
    # unrounded counts put it up to half a count off (a whole cm at 2 cm a count).
    k = round(depth_cm * 100 / (depth_raw - zero))
    if k == 0:  # (sdk 0 is in range, but then every depth reads 0)
        raise CalibrationError(
            f"k would round to 0: {depth_cm} cm over {counts:g} counts is finer than sdk can "
            "say (k is in hundredths of a cm per count)"
        )
    if not k_arg.check(k):
        raise CalibrationError(
            f"k would be {k}, outside sdk's range {k_arg.range_text()}: "
            f"{depth_cm} cm over {counts:g} counts"
        )
    return Calibration(zero, k, surface_raw, depth_raw, depth_cm)
