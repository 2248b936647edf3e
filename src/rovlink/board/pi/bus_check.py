"""What an I²C failure means for the bus: one device gone, or the whole bus stuck.

A device reset in the middle of a transfer (a sensor's brown-out) can be left holding SDA low,
waiting for clock pulses that never come; then no transaction on the bus gets through, to any
device, and the PWM boards keep making their last pulses. The standard recovery (nine clock
pulses on SCL, then a STOP) is not done here: on a Raspberry Pi, SCL belongs to the kernel's I²C
controller (GPIO 3 in its ALT0 function), and toggling it from user space means taking the pin
from the kernel driver in the middle of its transfers, which neither smbus2 nor gpiozero can do
safely or hand back. So a failure is probed (an address-only write to each device, as
``i2cdetect`` does) and said plainly, with what to do.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from rovlink.board.pi.i2c import I2cBus

__all__ = ["BusCheck", "check_bus"]


@dataclass(frozen=True)
class BusCheck:
    """Which devices of a bus answered a probe, and what that means."""

    bus_number: int
    answering: tuple[str, ...]
    silent: tuple[str, ...]

    @property
    def stuck(self) -> bool:
        """Whether no device answered: a stuck (or unpowered, or unwired) bus."""
        return bool(self.silent) and not self.answering

    def __str__(self) -> str:
        bus = f"I²C bus {self.bus_number}"
        if self.stuck:
            return (
                f"no device on {bus} answers ({', '.join(self.silent)}): the bus is stuck (SDA "
                "held low by a device reset in the middle of a transfer, as a sensor's "
                "brown-out leaves it) or has lost its 3.3 V or its wires; the controller cannot "
                "free it: cut the thruster power (the PWM boards keep their last pulses), power "
                "the I²C devices off and on (rebooting the Pi does not: its 3.3 V stays on), "
                f"check that `i2cdetect -y {self.bus_number}` lists them, then start the "
                "controller again"
            )
        if self.silent:
            return (
                f"on {bus}, {', '.join(self.silent)} does not answer while "
                f"{', '.join(self.answering)} does: check its wiring and its supply"
            )
        return f"every device on {bus} answers a probe now"


def check_bus(bus: I2cBus, bus_number: int, devices: Mapping[int, str]) -> BusCheck:
    """Probe each device of ``devices`` (address → name) with an address-only write."""
    answering: list[str] = []
    silent: list[str] = []
    for address, name in devices.items():
        try:
            bus.write(address, b"")
        except OSError:
            silent.append(name)
        else:
            answering.append(name)
    return BusCheck(bus_number, tuple(answering), tuple(silent))
