"""An I²C bus of simulated devices that records every transaction: for tests and dry runs.

``[i2c] backend = "fake"`` in ``rov.toml`` runs the whole board on this bus, so the controller,
its safety paths and a host program can be exercised on any computer; with ``fake_log`` every
transaction is also written to a file as one JSON line, which is how tests watch the pulses of a
``rovlink controller --board pi`` process. The devices answer as the datasheets describe (the
sensors' calibration is the datasheets' example; a test sets what they read); nothing here
reaches hardware.
"""

from __future__ import annotations

import errno
import json
import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import IO, Protocol

from rovlink.board.pi.ms5837 import Ms5837Model, compensate, crc4

__all__ = [
    "MS5837_EXAMPLES",
    "FakeAds1115",
    "FakeBno055",
    "FakeDevice",
    "FakeI2cBus",
    "FakeMs5837",
    "FakePca9685",
    "Transaction",
    "ms5837_conversions",
    "ms5837_prom",
]


class FakeDevice(Protocol):
    """A device on the fake bus, seen at the level of raw transactions."""

    def write(self, data: bytes) -> None:
        """A write transaction's bytes."""
        ...

    def read(self, length: int) -> bytes:
        """A read transaction (after a write, if there was one, as a repeated start)."""
        ...


@dataclass(frozen=True, slots=True)
class Transaction:
    """One transaction as a logic analyser would show it."""

    address: int
    written: bytes
    read: bytes = b""
    failed: bool = False

    def to_json(self) -> str:
        """One JSON line."""
        return json.dumps(
            {
                "address": self.address,
                "written": self.written.hex(),
                "read": self.read.hex(),
                "failed": self.failed,
            }
        )

    @classmethod
    def from_json(cls, line: str) -> Transaction:
        """A transaction back from :meth:`to_json`."""
        item = json.loads(line)
        return cls(
            item["address"],
            bytes.fromhex(item["written"]),
            bytes.fromhex(item["read"]),
            item["failed"],
        )


class FakeI2cBus:
    """An :class:`~rovlink.board.pi.i2c.I2cBus` of fake devices, recording every transaction.

    ``fail(address, count)`` makes the next ``count`` transactions with that address fail as a
    device that stopped answering does (``OSError`` EREMOTEIO).
    """

    def __init__(self, devices: dict[int, FakeDevice], log: IO[str] | None = None) -> None:
        self.devices = devices
        self.transactions: list[Transaction] = []
        self._log = log
        self._failures: dict[int, int] = {}
        self._lock = threading.Lock()

    def snapshot(self) -> list[Transaction]:
        """Every transaction so far (a copy: the bus may be in use in another thread)."""
        with self._lock:
            return list(self.transactions)

    def fail(self, address: int, count: int) -> None:
        """Fail the next ``count`` transactions with ``address``."""
        with self._lock:
            self._failures[address] = count

    def write(self, address: int, data: bytes) -> None:
        """One write transaction."""
        self._transact(address, data, 0)

    def read(self, address: int, length: int) -> bytes:
        """One read transaction."""
        return self._transact(address, b"", length)

    def write_read(self, address: int, data: bytes, length: int) -> bytes:
        """A write, a repeated start, a read."""
        return self._transact(address, data, length)

    def close(self) -> None:
        """Close the log."""
        if self._log is not None:
            self._log.close()
            self._log = None

    def _transact(self, address: int, data: bytes, length: int) -> bytes:
        with self._lock:
            device = self.devices.get(address)
            failing = self._failures.get(address, 0)
            if failing:
                self._failures[address] = failing - 1
            if device is None or failing:
                self._record(Transaction(address, bytes(data), failed=True))
                raise OSError(errno.EREMOTEIO, f"no acknowledge from {address:#04x}")
            if data or not length:
                device.write(bytes(data))
            answer = device.read(length) if length else b""
            self._record(Transaction(address, bytes(data), answer))
            return answer

    def _record(self, transaction: Transaction) -> None:
        self.transactions.append(transaction)
        if self._log is not None:
            self._log.write(transaction.to_json() + "\n")
            self._log.flush()


class _Registers:
    """A register file with an address pointer, as most I²C devices have."""

    def __init__(self, size: int = 256) -> None:
        self.registers = bytearray(size)
        self.pointer = 0

    def write(self, data: bytes) -> None:
        if not data:
            return
        self.pointer = data[0]
        for offset, value in enumerate(data[1:]):
            self._store((self.pointer + offset) % len(self.registers), value)

    def read(self, length: int) -> bytes:
        return bytes(
            self.registers[(self.pointer + offset) % len(self.registers)]
            for offset in range(length)
        )

    def _store(self, register: int, value: int) -> None:
        self.registers[register] = value


class _PoweredRegisters(_Registers):
    """A register file that starts, and comes back from a supply dip, with its power-on values
    (:meth:`power_on_reset`; ``power_on_resets`` counts them)."""

    def __init__(self, size: int = 256) -> None:
        super().__init__(size)
        self.power_on_resets = 0
        self._load_power_on_values()

    def power_on_reset(self) -> None:
        """The registers back to their power-on values, as a supply dip (a brown-out) leaves
        them on a real chip."""
        self.power_on_resets += 1
        self._load_power_on_values()

    def _load_power_on_values(self) -> None:
        raise NotImplementedError


#: The PCA9685's registers after power-on (datasheet §7.3, table 4): MODE1 SLEEP and ALLCALL
#: (auto-increment off), MODE2 OUTDRV, the sub-addresses and ALLCALL address, every output's
#: LEDn_OFF_H with its full-off bit, PRE_SCALE 0x1E (200 Hz); every other register 0.
_PCA9685_POWER_ON: dict[int, int] = {
    0x00: 0x11,
    0x01: 0x04,
    0x02: 0xE2,
    0x03: 0xE4,
    0x04: 0xE8,
    0x05: 0xE0,
    **{0x09 + 4 * channel: 0x10 for channel in range(16)},
    0xFD: 0x10,
    0xFE: 0x1E,
}


class FakePca9685(_PoweredRegisters):
    """A PCA9685: its registers, and the pulse each output makes.

    :meth:`power_on_reset` puts the registers back as after power-on, as a supply dip (a
    brown-out) does on a real chip: asleep, outputs off, the prescale and mode at their defaults.
    """

    def __init__(self, oscillator_hz: float = 25_000_000.0) -> None:
        super().__init__()
        self.oscillator_hz = oscillator_hz

    def _load_power_on_values(self) -> None:
        values = bytearray(len(self.registers))
        for register, value in _PCA9685_POWER_ON.items():
            values[register] = value
        self.registers[:] = values  # at once: the board loop's thread may be writing

    def write(self, data: bytes) -> None:
        if len(data) > 2 and not self.registers[0x00] & 0x20:
            # Auto-increment off (as after power-on): every byte lands in the same register.
            self.pointer = data[0]
            for value in data[1:]:
                self._store(self.pointer, value)
            return
        super().write(data)

    def _store(self, register: int, value: int) -> None:
        if register == 0xFE and not self.registers[0x00] & 0x10:
            return  # PRE_SCALE is written only while asleep (datasheet §7.3.5)
        if register == 0x00:
            value &= 0x7F  # RESTART: writing 1 clears it (it reads 1 only after a sleep)
        if 0xFA <= register <= 0xFD:  # ALL_LED_*: every output at once
            for channel in range(16):
                self.registers[0x06 + 4 * channel + register - 0xFA] = value
        self.registers[register] = value

    @property
    def sleeping(self) -> bool:
        """Whether the oscillator is off (no pulses at all)."""
        return bool(self.registers[0x00] & 0x10)

    @property
    def prescale(self) -> int:
        """The PRE_SCALE register."""
        return self.registers[0xFE]

    def pulse_us(self, channel: int) -> float | None:
        """The pulse on ``channel``, µs; None while it makes none (off, or asleep)."""
        base = 0x06 + 4 * channel
        on = self.registers[base] | (self.registers[base + 1] & 0x0F) << 8
        off = self.registers[base + 2] | (self.registers[base + 3] & 0x0F) << 8
        if self.sleeping or self.registers[base + 3] & 0x10:
            return None
        period_us = 4096 * (self.prescale + 1) / self.oscillator_hz * 1e6
        return (off - on) % 4096 * period_us / 4096


#: The datasheets' example calibration and conversions: (C1–C6, D1, D2), with the documented
#: results (first order): 30BA 3999.8 mbar at 19.81 °C, 02BA 1100.02 mbar at 20.00 °C.
MS5837_EXAMPLES: dict[Ms5837Model, tuple[tuple[int, ...], int, int]] = {
    Ms5837Model.BA30: ((34982, 36352, 20328, 22354, 26646, 26146), 4958179, 6815414),
    Ms5837Model.BA02: ((46372, 43981, 29059, 27842, 31553, 28165), 6465444, 8077636),
}
_FACTORY_BITS = 0x0A3C  # word 0's low 12 bits: factory data, any value


def ms5837_prom(coefficients: Sequence[int], factory_bits: int = _FACTORY_BITS) -> list[int]:
    """Seven PROM words for C1–C6 with a correct CRC-4 in word 0."""
    words = [factory_bits & 0x0FFF, *coefficients]
    words[0] |= crc4(words) << 12
    return words


_ADC_MAX = 2**24 - 1  # the conversions are 24-bit


def ms5837_conversions(
    model: Ms5837Model, prom: Sequence[int], pressure_mbar: float, temperature_c: float
) -> tuple[int, int]:
    """The D1 and D2 that :func:`~rovlink.board.pi.ms5837.compensate` (second order included)
    turns into the reading nearest ``pressure_mbar`` and ``temperature_c``: the datasheet's
    calculation run backwards by bisection, D2 first (the temperature depends on D2 alone), then
    D1 (the pressure rises with D1 at a given temperature).

    :class:`ValueError` names a value no 24-bit conversion reaches with this calibration.

    >>> prom = ms5837_prom(MS5837_EXAMPLES[Ms5837Model.BA30][0])
    >>> d1, d2 = ms5837_conversions(Ms5837Model.BA30, prom, 1257.68, 4.0)  # 2.5 m, cold
    >>> compensate(Ms5837Model.BA30, prom, d1, d2)
    Ms5837Reading(pressure_mbar=1257.7, temperature_c=4.0)
    """
    name = f"MS5837-{model.upper()}"
    if not (math.isfinite(pressure_mbar) and math.isfinite(temperature_c)):
        raise ValueError(
            f"{name}: a reading must be finite, got {pressure_mbar} mbar, {temperature_c} °C"
        )
    d2 = _nearest(
        lambda value: compensate(model, prom, 0, value).temperature_c,
        temperature_c,
        f"{name}: {temperature_c:g} °C",
    )
    d1 = _nearest(
        lambda value: compensate(model, prom, value, d2).pressure_mbar,
        pressure_mbar,
        f"{name}: {pressure_mbar:g} mbar at {temperature_c:g} °C",
    )
    return d1, d2


def _nearest(output: Callable[[int], float], target: float, what: str) -> int:
    """The conversion 1…2²⁴−1 whose ``output`` (non-decreasing) is nearest ``target``."""
    low, high = 1, _ADC_MAX
    lowest, highest = output(low), output(high)
    if not lowest <= target <= highest:
        raise ValueError(
            f"{what} is out of the sensor's reach: its conversions give {lowest:g}–{highest:g}"
        )
    while low < high:  # the first conversion whose output reaches the target
        middle = (low + high) // 2
        if output(middle) < target:
            low = middle + 1
        else:
            high = middle
    if low > 1 and target - output(low - 1) <= output(low) - target:
        return low - 1
    return low


@dataclass
class FakeMs5837:
    """An MS5837: reset, PROM reads, D1/D2 conversions and the ADC read.

    It converts ``d1`` and ``d2``: the datasheet's example values (:meth:`example`, about 30 m
    of water for the 30BA), or those of a reading set with :meth:`set_reading`.
    """

    prom: list[int]
    d1: int
    d2: int
    model: Ms5837Model = Ms5837Model.BA30
    resets: int = 0
    _answer: bytes = b""
    _converted: int = 0
    conversions: list[int] = field(default_factory=list)

    @classmethod
    def example(cls, model: Ms5837Model) -> FakeMs5837:
        """The datasheet's example device, converting the datasheet's example values."""
        coefficients, d1, d2 = MS5837_EXAMPLES[model]
        return cls(ms5837_prom(coefficients), d1, d2, model)

    @classmethod
    def reading(
        cls, model: Ms5837Model, pressure_mbar: float, temperature_c: float = 20.0
    ) -> FakeMs5837:
        """The datasheet's example calibration, reading ``pressure_mbar`` at ``temperature_c``
        (to the sensor's resolution: 0.1 mbar for the 30BA, 0.01 mbar for the 02BA)."""
        fake = cls.example(model)
        fake.set_reading(pressure_mbar, temperature_c)
        return fake

    def set_reading(self, pressure_mbar: float, temperature_c: float = 20.0) -> None:
        """Convert to this reading from the next conversion on; :class:`ValueError` if the
        sensor cannot reach it."""
        d1, d2 = ms5837_conversions(self.model, self.prom, pressure_mbar, temperature_c)
        self.d1, self.d2 = d1, d2

    def power_on_reset(self) -> None:
        """As after a supply dip: a conversion in progress is lost, so the next ADC read gives
        0 (datasheet), after which the driver sends the reset command."""
        self._converted = 0
        self._answer = b""

    def write(self, data: bytes) -> None:
        if not data:  # a quick write (a probe): the chip acknowledges its address, nothing more
            return
        command = data[0]
        if command == 0x1E:  # a conversion under way is lost (datasheet)
            self.resets += 1
            self._converted = 0
        elif 0xA0 <= command <= 0xAE:
            self._answer = self.prom[(command - 0xA0) // 2].to_bytes(2, "big")
        elif 0x40 <= command <= 0x4A:
            self._converted = self.d1
            self.conversions.append(command)
        elif 0x50 <= command <= 0x5A:
            self._converted = self.d2
            self.conversions.append(command)
        elif command == 0x00:
            # A conversion is read once; a repeated read gives 0 (datasheet).
            self._answer = self._converted.to_bytes(3, "big")
            self._converted = 0

    def read(self, length: int) -> bytes:
        return self._answer[:length].ljust(length, b"\x00")


#: The ADS1115's config register after power-on: single-shot, powered down, AIN0–AIN1, ±2.048 V.
_ADS1115_POWER_ON_CONFIG = 0x8583
_ADS1115_SINGLE_SHOT = 0x0100


class FakeAds1115(_PoweredRegisters):
    """An ADS1115 whose input sits at ``volts``, converting continuously once a driver says so.

    :meth:`power_on_reset` puts it back as after power-on (a supply dip): powered down, its
    conversion register 0.
    """

    def __init__(self, volts: float) -> None:
        super().__init__(size=4)
        self.volts = volts

    def _load_power_on_values(self) -> None:
        self.registers[1:3] = _ADS1115_POWER_ON_CONFIG.to_bytes(2, "big")

    def read(self, length: int) -> bytes:
        if self.pointer == 0x00:
            config = int.from_bytes(self.registers[1:3], "big")
            if config & _ADS1115_SINGLE_SHOT:
                return bytes(length)  # powered down: the conversion register keeps its 0
            full_scale_v = (6.144, 4.096, 2.048, 1.024, 0.512, 0.256, 0.256, 0.256)[
                (config >> 9) & 0x7
            ]
            counts = max(-32768, min(32767, round(self.volts / full_scale_v * 32768)))
            return counts.to_bytes(2, "big", signed=True)[:length]
        return bytes(self.registers[1:3])[:length]  # the config register

    def _store(self, register: int, value: int) -> None:
        # Registers are 16 bits: a write after the pointer is MSB then LSB.
        if self.pointer == 0x01:
            self.registers[1 + (register - 0x01) % 2] = value


class FakeBno055(_PoweredRegisters):
    """A BNO055 reporting a fixed attitude (heading, roll, pitch in degrees) once a driver has
    put it in a fusion mode; :meth:`power_on_reset` puts it back in config mode with the default
    axis map, as a supply dip or a reset of its own does."""

    def __init__(self, roll_deg: float = 2.0, pitch_deg: float = -1.0, heading_deg: float = 90.0):
        super().__init__()
        self.registers[0x00] = 0xA0  # CHIP_ID
        self.set_attitude(roll_deg, pitch_deg, heading_deg)

    def _load_power_on_values(self) -> None:
        """Config mode (no fusion) and placement P1's axis map."""
        self.registers[0x3D] = 0x00  # OPR_MODE: config
        self.registers[0x41] = 0x24  # AXIS_MAP_CONFIG: P1
        self.registers[0x42] = 0x00  # AXIS_MAP_SIGN: P1

    def set_attitude(self, roll_deg: float, pitch_deg: float, heading_deg: float) -> None:
        """What the Euler registers report (1/16 degree, little-endian)."""
        for offset, value in enumerate((heading_deg, roll_deg, pitch_deg)):
            self.registers[0x1A + 2 * offset : 0x1C + 2 * offset] = round(value * 16).to_bytes(
                2, "little", signed=True
            )

    def _store(self, register: int, value: int) -> None:
        if register == 0x3F and value & 0x20:  # SYS_TRIGGER RST_SYS
            self._load_power_on_values()
            return
        if 0x1A <= register <= 0x1F:
            return  # read-only
        self.registers[register] = value
