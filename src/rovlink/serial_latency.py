"""A serial port's low-latency mode: replies handed to the program at once, not batched.

A USB serial adapter holds what it receives until its buffer fills or a timer runs out: an FTDI
chip's latency timer is 16 ms by default, so every reply of a query is up to 16 ms late, and a
loop that polls the robot runs at a fraction of the line's rate. Linux drivers that have such a
timer (``ftdi_sio``) set it to 1 ms when a program asks for low latency (``ASYNC_LOW_LATENCY``,
pyserial's :meth:`set_low_latency_mode`), as robot serial drivers do. Both ends ask for it when
they open a serial device: the host's client and a board's controller. Standard library only,
besides the pyserial port object it is given.
"""

from __future__ import annotations

import logging
from typing import Any

__all__ = ["ask_for_low_latency"]

logger = logging.getLogger(__name__)


def ask_for_low_latency(port: Any, name: str) -> bool:
    """Ask the driver of pyserial ``port`` for low latency; whether it took it. A port that
    cannot (a pseudo-terminal, a UART without a timer, another system) stays as it was.

    Example::

        port = serial.Serial("/dev/ttyUSB0", 115200)
        ask_for_low_latency(port, "/dev/ttyUSB0")   # True on an FTDI adapter
    """
    set_low_latency_mode = getattr(port, "set_low_latency_mode", None)
    if set_low_latency_mode is None:
        return False
    try:
        set_low_latency_mode(True)
    except (ValueError, OSError) as error:  # (pyserial raises ValueError for the ioctl's error)
        logger.debug("%s: no low-latency mode (%s)", name, error)
        return False
    logger.debug("%s: low-latency mode on", name)
    return True
