"""The I²C bus as the drivers see it: raw transactions, on smbus2 or on a test double.

The drivers speak in the datasheets' terms (write these bytes, read that many, or both with a
repeated start), so each is a line-for-line reading of its datasheet and a fake bus can record
exactly what a logic analyser would see. :class:`Smbus2Bus` carries the transactions to Linux's
``/dev/i2c-N`` through smbus2's ``I2C_RDWR``; :class:`BusioAdapter` lends the same bus to
Adafruit's CircuitPython drivers, which expect a ``busio.I2C``.
"""

from __future__ import annotations

import threading
from typing import Protocol

__all__ = ["BusioAdapter", "I2cBus", "Smbus2Bus", "check_address"]


def check_address(address: int) -> int:
    """``address`` if it is a 7-bit address a device may have, else :class:`ValueError`."""
    if not 0x03 <= address <= 0x77:
        raise ValueError(f"I²C address must be 0x03–0x77, got {address:#04x}")
    return address


class I2cBus(Protocol):
    """An I²C bus master. Every method raises :class:`OSError` when the device does not answer."""

    def write(self, address: int, data: bytes) -> None:
        """One write transaction (``data`` may be empty: a quick write that probes the device)."""
        ...

    def read(self, address: int, length: int) -> bytes:
        """One read transaction of ``length`` bytes."""
        ...

    def write_read(self, address: int, data: bytes, length: int) -> bytes:
        """Write ``data``, then a repeated start and read ``length`` bytes (a register read)."""
        ...

    def close(self) -> None:
        """Release the bus."""
        ...


class Smbus2Bus:
    """``/dev/i2c-<number>`` through smbus2 (raw transactions with ``I2C_RDWR``)."""

    def __init__(self, number: int) -> None:
        from smbus2 import SMBus  # noqa: PLC0415 - the pi extra, needed on the board only

        self.number = number
        self._bus = SMBus(number)

    def write(self, address: int, data: bytes) -> None:
        """One write transaction."""
        from smbus2 import i2c_msg  # noqa: PLC0415

        self._bus.i2c_rdwr(i2c_msg.write(address, data))

    def read(self, address: int, length: int) -> bytes:
        """One read transaction."""
        from smbus2 import i2c_msg  # noqa: PLC0415

        message = i2c_msg.read(address, length)
        self._bus.i2c_rdwr(message)
        return bytes(message)

    def write_read(self, address: int, data: bytes, length: int) -> bytes:
        """A write, a repeated start, a read."""
        from smbus2 import i2c_msg  # noqa: PLC0415

        message = i2c_msg.read(address, length)
        self._bus.i2c_rdwr(i2c_msg.write(address, data), message)
        return bytes(message)

    def close(self) -> None:
        """Close the device file."""
        self._bus.close()


class BusioAdapter:
    """An :class:`I2cBus` with the interface of CircuitPython's ``busio.I2C``.

    Adafruit's drivers (the BNO055's among them) take a ``busio.I2C``; this lends them the bus
    the other drivers use, so that every device shares one bus object, one lock and, in tests,
    one record of transactions.
    """

    def __init__(self, bus: I2cBus) -> None:
        self._bus = bus
        self._lock = threading.Lock()

    def try_lock(self) -> bool:
        """Take the bus (busio's cooperative lock)."""
        return self._lock.acquire(blocking=False)

    def unlock(self) -> None:
        """Release the bus."""
        self._lock.release()

    def writeto(
        self, address: int, buffer: bytes | bytearray, *, start: int = 0, end: int | None = None
    ) -> None:
        """Write ``buffer[start:end]``."""
        self._bus.write(address, bytes(buffer[start:end]))

    def readfrom_into(
        self, address: int, buffer: bytearray, *, start: int = 0, end: int | None = None
    ) -> None:
        """Read into ``buffer[start:end]``."""
        stop = len(buffer) if end is None else end
        buffer[start:stop] = self._bus.read(address, stop - start)

    def writeto_then_readfrom(
        self,
        address: int,
        buffer_out: bytes | bytearray,
        buffer_in: bytearray,
        *,
        out_start: int = 0,
        out_end: int | None = None,
        in_start: int = 0,
        in_end: int | None = None,
    ) -> None:
        """Write ``buffer_out[out_start:out_end]``, then read ``buffer_in[in_start:in_end]``."""
        stop = len(buffer_in) if in_end is None else in_end
        data = bytes(buffer_out[out_start:out_end])
        buffer_in[in_start:stop] = self._bus.write_read(address, data, stop - in_start)

    def scan(self) -> list[int]:
        """The addresses that acknowledge a quick write."""
        found = []
        for address in range(0x03, 0x78):
            try:
                self._bus.write(address, b"")
            except OSError:
                continue
            found.append(address)
        return found

    def deinit(self) -> None:
        """Nothing to release: the bus belongs to its owner."""
