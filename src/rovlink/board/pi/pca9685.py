"""The NXP PCA9685 16-channel PWM controller, from its datasheet, on an :class:`I2cBus`.

A small driver of its own rather than Adafruit's: the controller needs three things the
datasheet states plainly (the prescale formula, the start-up order that makes the first pulse
an ESC sees a neutral one, and one auto-incremented write for several channels per control
period), and on this bus it needs no Blinka platform layer. It is ~100 lines a reader can check
against the datasheet line by line.
"""

from __future__ import annotations

import time
from collections.abc import Mapping

from rovlink.board.pi.i2c import I2cBus, check_address

__all__ = [
    "ALL_CALL_ADDRESS",
    "CHANNELS",
    "DEFAULT_OSCILLATOR_HZ",
    "FIRST_ADDRESS",
    "Pca9685",
    "prescale_for",
]

#: Outputs on the chip, numbered 0–15.
CHANNELS = 16
#: The chip's address with A5–A0 low; its six address pins add 0–63 (datasheet §7.1.1).
FIRST_ADDRESS = 0x40
#: The LED All Call address, which every PCA9685 answers after power-on or a reset (datasheet
#: §7.1.3): a chip strapped to it would have its writes land in every other chip that reset.
ALL_CALL_ADDRESS = 0x70
#: The internal oscillator's nominal frequency (datasheet §7.3.5); real chips are within ±5 %.
DEFAULT_OSCILLATOR_HZ = 25_000_000.0
_STEPS = 4096  # 12-bit counter

# Registers (datasheet §7.3).
MODE1 = 0x00
MODE2 = 0x01
LED0_ON_L = 0x06
ALL_LED_ON_L = 0xFA
PRE_SCALE = 0xFE
# MODE1 bits.
RESTART = 0x80
AUTO_INCREMENT = 0x20
SLEEP = 0x10
# MODE2 bits.
OUTDRV_TOTEM_POLE = 0x04
# LEDn_OFF_H bit 4: the output is fully off.
_FULL_OFF = 0x10
#: MODE1 while the outputs run (RESTART aside): awake, auto-increment on, ALLCALL off.
_MODE1_RUNNING = AUTO_INCREMENT
#: The oscillator needs 500 µs to start after SLEEP is cleared (datasheet §7.3.1.1).
_OSCILLATOR_START_S = 0.0005
_MIN_PRESCALE = 3  # the chip clamps lower values to 3
_MAX_PRESCALE = 255


def prescale_for(frequency_hz: float, oscillator_hz: float = DEFAULT_OSCILLATOR_HZ) -> int:
    """The PRE_SCALE value for an output frequency (datasheet §7.3.5, equation 1).

    prescale = round(osc_clock / (4096 × update_rate)) − 1

    >>> prescale_for(50.0), prescale_for(200.0)
    (121, 30)
    """
    prescale = round(oscillator_hz / (_STEPS * frequency_hz)) - 1
    if not _MIN_PRESCALE <= prescale <= _MAX_PRESCALE:
        low = oscillator_hz / (_STEPS * (_MAX_PRESCALE + 1))
        high = oscillator_hz / (_STEPS * (_MIN_PRESCALE + 1))
        raise ValueError(f"PWM frequency must be {low:.0f}–{high:.0f} Hz, got {frequency_hz:g}")
    return prescale


class Pca9685:
    """One PCA9685: 16 outputs of pulses of a common frequency, set in microseconds."""

    def __init__(
        self, bus: I2cBus, address: int = 0x40, *, oscillator_hz: float = DEFAULT_OSCILLATOR_HZ
    ) -> None:
        self.bus = bus
        self.address = check_address(address)
        self.oscillator_hz = oscillator_hz
        self.prescale: int | None = None
        self.frequency_hz: float | None = None
        self._counts: dict[int, int] = {}

    @property
    def period_us(self) -> float:
        """The actual period of the outputs, µs (from the prescale, not the frequency asked)."""
        if self.prescale is None:
            raise RuntimeError("the PCA9685 has not been started")
        return _STEPS * (self.prescale + 1) / self.oscillator_hz * 1e6

    def counts(self, pulse_us: float) -> int:
        """The OFF count (0–4095) of a pulse of ``pulse_us`` that starts at count 0."""
        counts = round(pulse_us * _STEPS / self.period_us)
        if not 0 <= counts < _STEPS:
            raise ValueError(
                f"a {pulse_us:g} µs pulse does not fit in the {self.period_us:.0f} µs period"
            )
        return counts

    def start(self, frequency_hz: float, pulses_us: Mapping[int, float]) -> None:
        """Set the frequency and start with every output off except ``pulses_us`` (channel: µs).

        The order matters to ESCs: the oscillator is asleep while the prescale and the first
        pulses are written, so the first pulse on an output is the one given here (neutral, to
        arm an ESC), never a stale value from before.
        """
        prescale = prescale_for(frequency_hz, self.oscillator_hz)
        write = self.bus.write
        address = self.address
        write(address, bytes([MODE1, SLEEP | AUTO_INCREMENT]))
        write(address, bytes([ALL_LED_ON_L, 0, 0, 0, _FULL_OFF]))
        write(address, bytes([PRE_SCALE, prescale]))
        self.prescale = prescale
        self.frequency_hz = frequency_hz
        self._counts.clear()
        self.set_pulses_us(pulses_us)
        write(address, bytes([MODE2, OUTDRV_TOTEM_POLE]))
        write(address, bytes([MODE1, _MODE1_RUNNING]))
        time.sleep(_OSCILLATOR_START_S)
        write(address, bytes([MODE1, RESTART | _MODE1_RUNNING]))

    def take_over(
        self,
        frequency_hz: float,
        pulses_us: Mapping[int, float],
        start_pulses_us: Mapping[int, float],
    ) -> bool:
        """Set ``pulses_us`` on a chip another process started (a controller that died without
        setting neutral); whether it had to be started.

        A chip running as :meth:`start` leaves it at ``frequency_hz`` (MODE1 and PRE_SCALE
        read back) gets only ``pulses_us``: its other outputs (a servo claw) keep their pulses.
        Any other chip (reset by a supply dip, never started, not answering the read-back) is
        started with ``start_pulses_us``, the others off.
        """
        self.prescale = prescale_for(frequency_hz, self.oscillator_hz)
        self.frequency_hz = frequency_hz
        try:
            found = self.reset_found()
        except OSError:
            found = "no answer to the read-back"
        if found is None:
            self._counts.clear()
            self.set_pulses_us(pulses_us)
            return False
        self.start(frequency_hz, start_pulses_us)
        return True

    def reset_found(self) -> str | None:
        """Read MODE1 and PRE_SCALE back (two one-byte register reads); what differs from what
        :meth:`start` wrote, or None if both are as written.

        A chip that lost its supply for a moment (a brown-out) comes back as after power-on:
        asleep, auto-increment off, every output off, the prescale at 200 Hz. Its writes are
        still acknowledged, so only reading back shows it. RESTART is not compared: the chip
        sets it on its own after a sleep with outputs running, and it says nothing of the
        pulses. Raises :class:`OSError` when the chip does not answer.
        """
        if self.prescale is None:
            raise RuntimeError("the PCA9685 has not been started")
        mode1 = self._read_register(MODE1)
        prescale = self._read_register(PRE_SCALE)
        differences = []
        if mode1 & ~RESTART != _MODE1_RUNNING:
            differences.append(f"MODE1 reads {mode1:#04x}, not {_MODE1_RUNNING:#04x}")
        if prescale != self.prescale:
            differences.append(f"PRE_SCALE reads {prescale:#04x}, not {self.prescale:#04x}")
        if not differences:
            return None
        asleep = " (asleep: no pulses)" if mode1 & SLEEP else ""
        return ", ".join(differences) + asleep

    def _read_register(self, register: int) -> int:
        return self.bus.write_read(self.address, bytes([register]), 1)[0]

    def set_pulses_us(self, pulses_us: Mapping[int, float]) -> None:
        """Set the pulse width of some outputs; only changed outputs are written.

        Changed outputs on consecutive channels go out in one auto-incremented write.
        """
        changed = {}
        for channel, pulse_us in pulses_us.items():
            if not 0 <= channel < CHANNELS:
                raise ValueError(f"PCA9685 channel must be 0–{CHANNELS - 1}, got {channel}")
            counts = self.counts(pulse_us)
            if self._counts.get(channel) != counts:
                changed[channel] = counts
        for first, run in _consecutive_runs(changed):
            data = bytearray([LED0_ON_L + 4 * first])
            for counts in run:
                data += bytes([0, 0, counts & 0xFF, counts >> 8])
            self.bus.write(self.address, bytes(data))
            for offset, counts in enumerate(run):
                self._counts[first + offset] = counts

    def pulse_us(self, channel: int) -> float | None:
        """The pulse last written to ``channel``, µs (rounded to the counter), None if off."""
        counts = self._counts.get(channel)
        return None if counts is None else counts * self.period_us / _STEPS

    def forget_written(self) -> None:
        """Write every output again on the next call (after a bus error left them unknown)."""
        self._counts.clear()


def _consecutive_runs(values: Mapping[int, int]) -> list[tuple[int, list[int]]]:
    """``{0: a, 1: b, 5: c}`` → ``[(0, [a, b]), (5, [c])]``."""
    runs: list[tuple[int, list[int]]] = []
    for channel in sorted(values):
        if runs and runs[-1][0] + len(runs[-1][1]) == channel:
            runs[-1][1].append(values[channel])
        else:
            runs.append((channel, [values[channel]]))
    return runs
