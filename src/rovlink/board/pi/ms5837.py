"""The TE MS5837 pressure sensor (Blue Robotics Bar30 = MS5837-30BA, Bar02 = MS5837-02BA).

Written from TE's datasheets: reset, the PROM's calibration words and their CRC-4, D1 (pressure)
and D2 (temperature) conversions, and the first- and second-order compensation, which differ
between the two models. A conversion takes up to 18 ms, longer than a control period, so the
driver never waits for one: :meth:`Ms5837.poll` starts a conversion and collects it on a later
call, alternating D1 and D2, and returns a reading whenever a pair is complete.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

from rovlink.board.board import MonotonicClock
from rovlink.board.pi.i2c import I2cBus, check_address
from rovlink.board.sensors import SensorError
from rovlink.controller import Clock
from rovlink.logs import get_logger
from rovlink.protocol.text_enum import StrEnum

__all__ = [
    "OVERSAMPLING",
    "PRODUCT_VERSIONS",
    "Ms5837",
    "Ms5837Model",
    "Ms5837Reading",
    "compensate",
    "crc4",
    "product_version",
]

logger = get_logger(__name__)

_RESET = 0x1E
_ADC_READ = 0x00
_PROM_READ = 0xA0
_CONVERT_D1 = 0x40
_CONVERT_D2 = 0x50
_PROM_WORDS = 7
_RESET_S = 0.003  # reload of the PROM after a reset: 2.8 ms (datasheet)

#: The range of TEMP in the datasheets' calculation (−4000 to 8500, in 0.01 °C): a reading
#: outside it comes from a corrupt conversion.
_MIN_C = -40.0
_MAX_C = 85.0

#: Oversampling ratio → (command offset, maximum conversion time, s) from the datasheet.
OVERSAMPLING: dict[int, tuple[int, float]] = {
    256: (0x0, 0.00060),
    512: (0x2, 0.00117),
    1024: (0x4, 0.00228),
    2048: (0x6, 0.00454),
    4096: (0x8, 0.00904),
    8192: (0xA, 0.01808),
}


class Ms5837Model(StrEnum):
    """The two variants; their compensation formulas differ."""

    BA30 = "30ba"  # 0–30 bar (Bar30)
    BA02 = "02ba"  # 0–2 bar (Bar02)


#: Product versions (PROM word 0, bits 11–5) that name the model (TE's datasheets, "Version PROM
#: Word 0 programming"; the MS5837-30BA26 is the Bar30's part). Version 0 is an MS5837-02BA01
#: and an older MS5837-30BA01 alike, so it, like any version not listed, says nothing.
PRODUCT_VERSIONS: dict[int, tuple[str, Ms5837Model]] = {
    0x1A: ("MS5837-30BA26", Ms5837Model.BA30),
    0x15: ("MS5837-02BA21", Ms5837Model.BA02),
}


def product_version(word0: int) -> int:
    """The product version in PROM word 0 (bits 11–5).

    >>> hex(product_version(0x7348))  # CRC 7, version 0x1A (an MS5837-30BA26), factory bits 8
    '0x1a'
    """
    return (word0 >> 5) & 0x7F


class Ms5837Reading(NamedTuple):
    """One compensated reading."""

    pressure_mbar: float
    temperature_c: float


def crc4(words: Sequence[int]) -> int:
    """The CRC-4 of the PROM (datasheet, "CRC check"): over words 0–6 with word 0's top 4 bits
    (the CRC itself) cleared and an eighth word of 0.

    >>> crc4([0x0000, 1, 2, 3, 4, 5, 6]) == crc4([0xF000, 1, 2, 3, 4, 5, 6])
    True
    """
    prom = [words[0] & 0x0FFF, *words[1:_PROM_WORDS], 0]
    remainder = 0
    for count in range(16):
        word = prom[count >> 1]
        remainder ^= word & 0x00FF if count % 2 else word >> 8
        for _ in range(8):
            remainder = (remainder << 1) ^ 0x3000 if remainder & 0x8000 else remainder << 1
            remainder &= 0xFFFF
    return (remainder >> 12) & 0x000F


def compensate(
    model: Ms5837Model, prom: Sequence[int], d1: int, d2: int, *, second_order: bool = True
) -> Ms5837Reading:
    """Pressure and temperature from the raw conversions (datasheet, "Pressure and temperature
    calculation" and "Second order temperature compensation"); integer arithmetic as there.

    ``prom`` is the seven PROM words (C1–C6 are ``prom[1]``–``prom[6]``).
    """
    c1, c2, c3, c4, c5, c6 = prom[1:7]
    dt = d2 - c5 * 2**8
    temp = 2000 + dt * c6 // 2**23
    if model is Ms5837Model.BA30:
        off = c2 * 2**16 + (c4 * dt) // 2**7
        sens = c1 * 2**15 + (c3 * dt) // 2**8
    else:
        off = c2 * 2**17 + (c4 * dt) // 2**6
        sens = c1 * 2**16 + (c3 * dt) // 2**7
    ti = offi = sensi = 0
    if second_order:
        ti, offi, sensi = _second_order(model, dt, temp)
    off -= offi
    sens -= sensi
    temperature_c = (temp - ti) / 100.0
    if model is Ms5837Model.BA30:
        pressure_mbar = ((d1 * sens // 2**21 - off) // 2**13) / 10.0  # 0.1 mbar steps
    else:
        pressure_mbar = ((d1 * sens // 2**21 - off) // 2**15) / 100.0  # 0.01 mbar steps
    return Ms5837Reading(pressure_mbar, temperature_c)


def _second_order(model: Ms5837Model, dt: int, temp: int) -> tuple[int, int, int]:
    """(Ti, OFFi, SENSi) of the second-order compensation."""
    if model is Ms5837Model.BA30:
        if temp < 2000:  # low temperature
            ti = 3 * dt * dt // 2**33
            offi = 3 * (temp - 2000) ** 2 // 2
            sensi = 5 * (temp - 2000) ** 2 // 2**3
            if temp < -1500:  # very low temperature
                offi += 7 * (temp + 1500) ** 2
                sensi += 4 * (temp + 1500) ** 2
            return ti, offi, sensi
        return 2 * dt * dt // 2**37, (temp - 2000) ** 2 // 2**4, 0
    if temp < 2000:
        return (
            11 * dt * dt // 2**35,
            31 * (temp - 2000) ** 2 // 2**3,
            63 * (temp - 2000) ** 2 // 2**5,
        )
    return 0, 0, 0


@dataclass
class _Cycle:
    """Where the D1/D2 cycle is: the conversion under way (or none: after a reset), and when
    it, or the reset, is done."""

    converting: int | None = None  # _CONVERT_D1 or _CONVERT_D2
    ready_s: float = 0.0
    d1: int | None = None


class Ms5837:
    """One MS5837 on an I²C bus (its address is fixed at 0x76).

    ``clock`` (default :func:`time.monotonic`, the board's) must be the clock of the ``now_s``
    given to :meth:`poll`: it is read after each convert command's write, where the conversion
    starts.
    """

    def __init__(
        self,
        bus: I2cBus,
        *,
        model: Ms5837Model = Ms5837Model.BA30,
        address: int = 0x76,
        oversampling: int = 4096,
        clock: Clock | None = None,
    ) -> None:
        if oversampling not in OVERSAMPLING:
            choices = ", ".join(map(str, OVERSAMPLING))
            raise ValueError(f"oversampling must be one of {choices}, got {oversampling}")
        self.bus = bus
        self.model = model
        self.address = check_address(address)
        self._osr_offset, self.conversion_s = OVERSAMPLING[oversampling]
        self._clock: Clock = clock if clock is not None else MonotonicClock()
        self.prom: tuple[int, ...] = ()
        self._cycle = _Cycle()

    def start(self) -> None:
        """Reset the sensor and read its calibration; :class:`SensorError` on a bad CRC-4, or
        when the PROM's product version names the other model."""
        self.bus.write(self.address, bytes([_RESET]))
        time.sleep(_RESET_S)
        prom = self.read_prom()
        version = product_version(prom[0])
        named = PRODUCT_VERSIONS.get(version)
        if named is not None and named[1] is not self.model:
            part, model = named
            raise SensorError(
                f"MS5837 at {self.address:#04x}: its PROM names it an {part} (product version "
                f"{version:#04x} in word 0), not the {self.model} it is set to be: set "
                f'[pressure.ms5837] model = "{model}"'
            )
        self.prom = prom
        self._cycle = _Cycle()

    def read_prom(self) -> tuple[int, ...]:
        """The seven PROM words, checked against the CRC-4 in word 0."""
        words = []
        for index in range(_PROM_WORDS):
            data = self.bus.write_read(self.address, bytes([_PROM_READ + 2 * index]), 2)
            words.append(int.from_bytes(data, "big"))
        if len(set(words)) == 1:
            # Seven zero words pass the CRC-4 (its remainder over zeros is 0) and compensate to
            # 0 mbar: another device at this address, or a bus that reads a constant.
            raise SensorError(
                f"MS5837 at {self.address:#04x}: every PROM word reads {words[0]:#06x}, no "
                "calibration: is an MS5837 at this address?"
            )
        stored = words[0] >> 12
        computed = crc4(words)
        if stored != computed:
            raise SensorError(
                f"MS5837 at {self.address:#04x}: PROM CRC-4 is {computed:#x}, "
                f"the PROM says {stored:#x}: calibration data corrupt"
            )
        return tuple(words)

    def poll(self, now_s: float) -> Ms5837Reading | None:
        """Advance the D1/D2 cycle without waiting; a reading when a D1–D2 pair completes."""
        cycle = self._cycle
        if now_s < cycle.ready_s:
            return None
        reading = None
        if cycle.converting is not None:
            try:
                value = self._read_adc()
            except SensorError:
                self._reset_after_lost_conversion()
                raise
            except OSError:
                self._cycle = _Cycle()  # start over with D1
                raise
            if cycle.converting == _CONVERT_D1:
                cycle.d1 = value
            elif cycle.d1 is not None:
                reading = compensate(self.model, self.prom, cycle.d1, value)
        command = _CONVERT_D2 if cycle.converting == _CONVERT_D1 else _CONVERT_D1
        cycle.converting = None
        self.bus.write(self.address, bytes([command + self._osr_offset]))
        cycle.converting = command
        # From the write's end, not the period's start: the write (and this period's reads
        # before it) may take milliseconds, and a read before the conversion ends gives 0.
        cycle.ready_s = self._clock.now_s() + self.conversion_s
        if reading is not None and not _MIN_C <= reading.temperature_c <= _MAX_C:
            # A corrupt D2 (a bit lost on a noisy bus) shifts the pressure too, often to a
            # plausible one; its temperature gives it away.
            raise SensorError(
                f"MS5837 at {self.address:#04x}: it reads {reading.temperature_c:g} °C, outside "
                f"the {_MIN_C:g}–{_MAX_C:g} °C of its datasheet: a corrupt conversion"
            )
        return reading

    def _reset_after_lost_conversion(self) -> None:
        """Send the reset command, and start the next conversion (D1) once it is done.

        A conversion read as 0 was lost: most likely the chip was reset by a supply dip, and
        after a power-on the datasheet has the reset command sent, which loads the calibration
        PROM into the chip's registers (and brings back a chip left in an unknown state). If
        the command itself fails, the cycle starts over with D1 and the next lost conversion
        tries again.
        """
        self._cycle = _Cycle()
        try:
            self.bus.write(self.address, bytes([_RESET]))
        except OSError as error:
            logger.debug(
                "MS5837 at %#04x: reset after a lost conversion failed: %s", self.address, error
            )
            return
        self._cycle = _Cycle(ready_s=self._clock.now_s() + _RESET_S)

    def _read_adc(self) -> int:
        value = int.from_bytes(self.bus.write_read(self.address, bytes([_ADC_READ]), 3), "big")
        if value == 0:  # the datasheet's answer to a read without a finished conversion
            raise SensorError(
                f"MS5837 at {self.address:#04x}: conversion read as 0 (lost; reset sent)"
            )
        return value
