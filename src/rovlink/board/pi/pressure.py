"""Pressure in mbar onto the protocol's raw scale (P13), so `qr`, `sdz`, `sdk` and `qd` keep
their meaning on a board whose sensor reports pressure rather than ADC counts."""

from __future__ import annotations

from dataclasses import dataclass

from rovlink.board.pi.ads1115 import Ads1115
from rovlink.board.pi.ms5837 import Ms5837, Ms5837Model
from rovlink.board.sensors import SensorError

__all__ = [
    "FULL_SCALE_MBAR",
    "LEAST_PLAUSIBLE_MBAR",
    "MIN_SCALE_K",
    "AnalogPressure",
    "AnalogTransducer",
    "Ms5837Pressure",
    "RawScale",
]

_GRAVITY_M_S2 = 9.80665
_PA_PER_MBAR = 100.0
_RAW_MAX = 1024
#: The smallest ``k`` the board can map pressure onto (the protocol's ``sdk`` allows 0).
MIN_SCALE_K = 1


@dataclass(frozen=True, slots=True)
class RawScale:
    """mbar → raw: the surface reads ``zero_raw``, each count is ``k / 100`` cm deeper.

    With the controller's [depth] ``zero_raw`` and ``k``, ``qd`` then reports the depth in cm.

    >>> scale = RawScale(zero_raw=20, k=200, surface_mbar=1013.25, density_kg_m3=1000.0)
    >>> scale.raw(1013.25), scale.raw(1013.25 + 98.0665)  # the surface, then 1 m down
    (20, 70)
    """

    zero_raw: int
    k: int
    surface_mbar: float
    density_kg_m3: float

    def __post_init__(self) -> None:
        # k = 0 is a valid `sdk` (every depth reads 0), but no pressure maps onto a scale of
        # 0 cm per count: refused here rather than a ZeroDivisionError at the first reading.
        if self.k < MIN_SCALE_K:
            raise ValueError(
                f"raw scale: k must be ≥ {MIN_SCALE_K} (k / 100 cm a count), got {self.k}"
            )

    def depth_cm(self, pressure_mbar: float) -> float:
        """The depth of water (of the configured density) that adds this pressure, cm."""
        pascal = (pressure_mbar - self.surface_mbar) * _PA_PER_MBAR
        return pascal / (self.density_kg_m3 * _GRAVITY_M_S2) * 100.0

    def raw(self, pressure_mbar: float) -> int:
        """The raw reading, 0–1024 (clipped, as an ADC clips)."""
        counts = self.zero_raw + self.depth_cm(pressure_mbar) * 100.0 / self.k
        return max(0, min(_RAW_MAX, round(counts)))


#: Less than the air on the highest summit: no reading of a sensor in air or water.
LEAST_PLAUSIBLE_MBAR = 300.0
#: The top of each model's range, mbar: 30 bar for the 30BA (its datasheet's operating range), 2 bar
#: for the 02BA (the 10 m a Bar02 is rated for; its compensated pressure is specified to 1.2 bar).
FULL_SCALE_MBAR: dict[Ms5837Model, float] = {
    Ms5837Model.BA30: 30_000.0,
    Ms5837Model.BA02: 2_000.0,
}
#: How far past its full scale a reading may go before it is taken for a corrupt conversion,
#: as a share of the range (the analog transducer's rule).
_OVER_RANGE_SHARE = 0.05


class Ms5837Pressure:
    """An MS5837 as the board's pressure source (raw scale).

    A reading below :data:`LEAST_PLAUSIBLE_MBAR` is a :class:`SensorError`, never a depth: the
    PROM of many parts does not say which model the sensor is (see
    :data:`~rovlink.board.pi.ms5837.PRODUCT_VERSIONS`), and a Bar30 computed as a Bar02 reads
    about a twentieth of its pressure, which the raw scale would clip to the surface at any depth.
    So is one more than 5 % of the model's range past its :data:`FULL_SCALE_MBAR`: a D1
    conversion corrupted on the bus (its temperature, from D2, still plausible) reads up to
    tens of bar, which the raw scale would clip to its deepest reading and a depth hold would
    answer with full up thrust.
    """

    def __init__(self, sensor: Ms5837, scale: RawScale) -> None:
        self.sensor = sensor
        self._scale = scale
        self.last_mbar: float | None = None

    def poll(self, now_s: float) -> int | None:
        """Advance the sensor's conversions; a raw value when a new reading is complete."""
        reading = self.sensor.poll(now_s)
        if reading is None:
            return None
        if reading.pressure_mbar < LEAST_PLAUSIBLE_MBAR:
            raise SensorError(
                f"it reads {reading.pressure_mbar:g} mbar, below any air or water "
                f"({LEAST_PLAUSIBLE_MBAR:g} mbar): is [pressure.ms5837] model right? "
                "(30ba: Bar30, 02ba: Bar02)"
            )
        model = self.sensor.model
        highest_mbar = FULL_SCALE_MBAR[model] * (1.0 + _OVER_RANGE_SHARE)
        if reading.pressure_mbar > highest_mbar:
            raise SensorError(
                f"it reads {reading.pressure_mbar:g} mbar, past the "
                f"{FULL_SCALE_MBAR[model]:g} mbar range of an MS5837-{model.upper()}: "
                "a corrupt conversion"
            )
        self.last_mbar = reading.pressure_mbar
        return self._scale.raw(reading.pressure_mbar)


@dataclass(frozen=True, slots=True)
class AnalogTransducer:
    """A transducer with a linear voltage output: ``min_volts`` at ``min_mbar`` to ``max_volts``
    at ``max_mbar``, as the ADC sees them. A voltage more than 5 % of the span outside is a fault
    (a broken wire reads 0 V), never a depth. The defaults are a 0.5–4.5 V transducer through
    the wiring guide's divider (× 2/3), as rov.toml's."""

    min_volts: float = 0.3333
    max_volts: float = 3.0
    min_mbar: float = 0.0
    max_mbar: float = 10000.0

    def mbar(self, volts: float) -> float:
        """The pressure for an output voltage; :class:`SensorError` outside the range."""
        span_v = self.max_volts - self.min_volts
        margin_v = 0.05 * span_v
        if not self.min_volts - margin_v <= volts <= self.max_volts + margin_v:
            raise SensorError(
                f"pressure transducer reads {volts:.3f} V, outside "
                f"{self.min_volts:g}–{self.max_volts:g} V: disconnected or faulty"
            )
        fraction = (volts - self.min_volts) / span_v
        return self.min_mbar + fraction * (self.max_mbar - self.min_mbar)


class AnalogPressure:
    """An analog transducer on an ADS1115 as the board's pressure source (raw scale)."""

    def __init__(self, adc: Ads1115, transducer: AnalogTransducer, scale: RawScale) -> None:
        self.adc = adc
        self._transducer = transducer
        self._scale = scale
        self.last_mbar: float | None = None

    def poll(self, now_s: float) -> int:
        """Read the latest conversion; the raw value.

        A converter reset by a supply dip is powered down and reads 0 V for ever. So a voltage
        out of the transducer's range, and a conversion of exactly 0 (inside the range of a
        transducer whose output starts at 0 V, where it would read as the lowest pressure at
        any depth), have the configuration read back and, if lost, written again; the reading
        then fails, and the next conversion counts.
        """
        volts = self.adc.read_volts()
        try:
            mbar = self._transducer.mbar(volts)
        except SensorError:
            self._raise_if_reset()
            raise
        if volts == 0.0:
            self._raise_if_reset()
        self.last_mbar = mbar
        return self._scale.raw(mbar)

    def _raise_if_reset(self) -> None:
        reset = self.adc.restart_if_reset()
        if reset is not None:
            raise SensorError(f"{reset}: continuous conversions started again") from None
