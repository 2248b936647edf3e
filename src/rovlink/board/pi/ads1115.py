"""The TI ADS1115 16-bit ADC, from its datasheet, reading an analog pressure transducer.

The converter runs in continuous mode, so a read is one register transaction and never waits
for a conversion.
"""

from __future__ import annotations

import time

from rovlink.board.pi.i2c import I2cBus, check_address

__all__ = ["DATA_RATES_SPS", "FULL_SCALES_V", "Ads1115", "config_word"]

_CONVERSION = 0x00
_CONFIG = 0x01
#: Full-scale range, V → PGA bits (datasheet table 8).
FULL_SCALES_V: dict[float, int] = {6.144: 0, 4.096: 1, 2.048: 2, 1.024: 3, 0.512: 4, 0.256: 5}
#: Samples per second → DR bits.
DATA_RATES_SPS: dict[int, int] = {8: 0, 16: 1, 32: 2, 64: 3, 128: 4, 250: 5, 475: 6, 860: 7}
_COMPARATOR_OFF = 0b11
_OS = 0x8000  # read: whether a conversion is under way; not part of the settings
_SINGLE_ENDED_MUX = 0b100  # AINx against GND: 0b100 + x


def config_word(channel: int, full_scale_v: float, data_rate_sps: int) -> int:
    """The config register for continuous conversions of AIN``channel`` against GND.

    >>> hex(config_word(0, 4.096, 128))
    '0x4283'
    """
    if not 0 <= channel <= 3:
        raise ValueError(f"ADS1115 channel must be 0–3, got {channel}")
    if full_scale_v not in FULL_SCALES_V:
        raise ValueError(f"full scale must be one of {sorted(FULL_SCALES_V)} V, got {full_scale_v}")
    if data_rate_sps not in DATA_RATES_SPS:
        raise ValueError(f"data rate must be one of {sorted(DATA_RATES_SPS)}, got {data_rate_sps}")
    mux = _SINGLE_ENDED_MUX + channel
    pga = FULL_SCALES_V[full_scale_v]
    rate = DATA_RATES_SPS[data_rate_sps]
    # MODE (bit 8) 0: continuous; comparator off.
    return (mux << 12) | (pga << 9) | (rate << 5) | _COMPARATOR_OFF


class Ads1115:
    """One ADS1115 converting one single-ended input continuously."""

    def __init__(
        self,
        bus: I2cBus,
        *,
        address: int = 0x48,
        channel: int = 0,
        full_scale_v: float = 4.096,
        data_rate_sps: int = 128,
    ) -> None:
        self.bus = bus
        self.address = check_address(address)
        self.full_scale_v = full_scale_v
        self._config = config_word(channel, full_scale_v, data_rate_sps)
        self._first_conversion_s = 2.0 / data_rate_sps

    def start(self) -> None:
        """Start continuous conversions; return once the first one is done."""
        self._write_config()
        time.sleep(self._first_conversion_s)

    def restart_if_reset(self) -> str | None:
        """Read the config register back; if it is not what :meth:`start` wrote (a supply dip
        reset the chip: powered down, its conversion register 0), write it again without
        waiting and say what was found. None if the chip is as configured."""
        data = self.bus.write_read(self.address, bytes([_CONFIG]), 2)
        found = int.from_bytes(data, "big")
        if found & ~_OS == self._config:
            return None
        self._write_config()
        return f"ADS1115 at {self.address:#04x} was reset (config {found:#06x})"

    def _write_config(self) -> None:
        self.bus.write(self.address, bytes([_CONFIG, *self._config.to_bytes(2, "big")]))

    def read_volts(self) -> float:
        """The latest conversion, V."""
        data = self.bus.write_read(self.address, bytes([_CONVERSION]), 2)
        return int.from_bytes(data, "big", signed=True) * self.full_scale_v / 32768
