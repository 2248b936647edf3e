"""The leak probe on a GPIO input through gpiozero, latched on the edge (P14).

gpiozero calls back on the input's edge from its own thread, so a pulse shorter than a control
period still sets the latch; the controller reads and clears it once per tick.
"""

from __future__ import annotations

import os
import tempfile
import threading
from typing import Any

__all__ = ["GpioLeakSensor"]

#: gpiozero reaches the pins through a pin library that the ``pi`` extra does not bring: on
#: Raspberry Pi OS it is the system's python3-lgpio.
NO_PIN_LIBRARY = (
    "gpiozero found no pin library: create the virtual environment with "
    "--system-site-packages (for the system's python3-lgpio) or pip install lgpio"
)


def _unwritable_working_directory() -> str | None:
    """The working directory if this process cannot create a file in it, else None.

    lgpio, gpiozero's pin library on a Pi, makes its notification pipes (``.lgd-nfy*``) in the
    working directory as it loads, and fails to load where it cannot: a service's is ``/``
    unless its unit says otherwise. Tried rather than asked (``os.access``), as root may be
    refused by the filesystem itself.
    """
    try:
        directory = os.getcwd()
    except OSError:  # removed since the process entered it
        return "(a removed directory)"
    try:
        with tempfile.TemporaryFile(dir=directory):
            return None
    except OSError:
        return directory


def _working_directory_hint() -> str:
    """What to say about the working directory when gpiozero found no pin library ("" when it
    can be written)."""
    directory = _unwritable_working_directory()
    if directory is None:
        return ""
    return (
        f"; the working directory {directory} cannot be written, and lgpio makes its "
        "notification pipes there: give the controller one it can (WorkingDirectory= in its "
        "systemd unit, as docs/hardware.md's)"
    )


class GpioLeakSensor:
    """A leak probe on GPIO ``pin`` (BCM numbering); ``active_high`` is wet at 3.3 V."""

    def __init__(
        self, pin: int, *, active_high: bool = True, pull: str = "down", pin_factory: Any = None
    ) -> None:
        from gpiozero import DigitalInputDevice  # noqa: PLC0415 - the pi extra

        self._lock = threading.Lock()
        self._fired = False
        if pull not in ("down", "up", "none"):
            raise ValueError(f"pull must be down, up or none, got {pull!r}")
        if pull != "none" and (pull == "down") != active_high:
            # gpiozero takes the active state from the pull: a pull-down input is active high.
            raise ValueError(
                f"a pull-{pull} input rests {'low' if pull == 'down' else 'high'}, so it "
                f"cannot be active {'high' if active_high else 'low'}"
            )
        try:
            if pull == "none":
                device = DigitalInputDevice(
                    pin, pull_up=None, active_state=active_high, pin_factory=pin_factory
                )
            else:
                device = DigitalInputDevice(pin, pull_up=pull == "up", pin_factory=pin_factory)
        except ImportError as error:
            # gpiozero loads its pin library with the first device: a missing one is a
            # ModuleNotFoundError (a factory named in GPIOZERO_PIN_FACTORY) or, when none of
            # its defaults loads, BadPinFactory, an ImportError of its own.
            raise RuntimeError(f"{error}; {NO_PIN_LIBRARY}{_working_directory_hint()}") from error
        except OSError as error:
            # lgpio named in GPIOZERO_PIN_FACTORY fails to load so ('.lgd-nfy-3': no such file).
            hint = _working_directory_hint()
            if not hint:
                raise
            raise RuntimeError(f"{error}{hint}") from error
        device.when_activated = self._on_wet
        self._device = device
        wet = bool(device.is_active)  # already wet at start
        with self._lock:  # kept if the callback latched a pulse since it was set
            self._fired = self._fired or wet

    def _on_wet(self) -> None:
        with self._lock:
            self._fired = True

    def fired_since_last_read(self) -> bool:
        """Whether the probe was wet at any moment since the last call; clears the latch."""
        with self._lock:
            fired = self._fired or bool(self._device.is_active)
            self._fired = False
        return fired

    def close(self) -> None:
        """Release the pin."""
        self._device.close()
