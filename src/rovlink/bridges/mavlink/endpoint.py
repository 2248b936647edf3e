"""The MAVLink endpoint: a pymavlink connection (MAVLink 2, ArduPilot's dialect) whose received
messages reach the event loop.

pymavlink's connections block, so one reader thread waits on the socket and hands each message
to the loop; everything is sent from the loop. Nothing here packs bytes: pymavlink does.
"""

from __future__ import annotations

import asyncio
import os
import socket
import threading
from collections.abc import Callable
from typing import Any

from rovlink.logs import get_logger

__all__ = ["SCHEMES", "MavlinkEndpoint", "check_address", "is_addressed_to"]

logger = get_logger("rovlink.bridges.mavlink")

#: The endpoint forms served, as pymavlink and MAVProxy write them.
SCHEMES = {
    "udpout": "send to a ground station listening there (QGroundControl: udpout:127.0.0.1:14550)",
    "udpin": "listen for a ground station there, answer whoever sent last",
    "tcpin": "listen for one ground station's TCP connection there",
    "tcp": "connect to a ground station's TCP server there",
}
_READ_TIMEOUT_S = 0.2  # how soon the reader thread notices it should stop
#: Messages whose target system field is not ``target_system`` (MANUAL_CONTROL's is ``target``).
_TARGET_SYSTEM_FIELD = {"MANUAL_CONTROL": "target"}
_BROADCAST = 0


def check_address(address: str) -> None:
    """Refuse an endpoint that is not ``SCHEME:HOST:PORT`` (``ValueError`` saying why).

    >>> check_address("udpout:127.0.0.1:14550")
    >>> check_address("udpout:127.0.0.1:0")
    Traceback (most recent call last):
    ...
    ValueError: MAVLink endpoint 'udpout:127.0.0.1:0': port must be 1–65535, got '0'
    """
    parts = address.split(":")
    schemes = ", ".join(SCHEMES)
    if len(parts) != 3 or parts[0] not in SCHEMES or not parts[1]:
        raise ValueError(
            f"MAVLink endpoint {address!r}: expected SCHEME:HOST:PORT with SCHEME one of {schemes}"
        )
    port = parts[2]
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ValueError(f"MAVLink endpoint {address!r}: port must be 1–65535, got {port!r}")


def is_addressed_to(message: Any, system_id: int, component_id: int) -> bool:
    """Whether ``message`` is for component ``component_id`` of system ``system_id``, by
    MAVLink's addressing: a target of 0 is a broadcast, a message without target fields is for
    everyone, and one for another component of this system is not this component's.
    """
    fields = message.get_fieldnames()
    system_field = _TARGET_SYSTEM_FIELD.get(message.get_type(), "target_system")
    if system_field in fields and getattr(message, system_field) not in (_BROADCAST, system_id):
        return False
    return "target_component" not in fields or message.target_component in (
        _BROADCAST,
        component_id,
    )


class MavlinkEndpoint:
    """One MAVLink connection as vehicle ``system_id``, component 1 (the autopilot)."""

    def __init__(self, address: str, *, system_id: int = 1) -> None:
        check_address(address)
        scheme, host, port = address.split(":")
        if scheme == "udpout":
            # pymavlink resolves an output's host only when it sends, and drops the error:
            # a name that does not resolve would be a bridge sending nowhere, silently.
            socket.getaddrinfo(host, int(port), type=socket.SOCK_DGRAM)
        # MAVLink 2 (pymavlink reads this when it loads a dialect): signatures aside, every
        # field of every message, and extensions such as SYS_STATUS's extended sensors.
        os.environ["MAVLINK20"] = "1"
        from pymavlink import mavutil  # noqa: PLC0415 - the mavlink extra loads only here

        self.address = address
        self.system_id = system_id
        self.component_id = 1
        self._connection: Any = mavutil.mavlink_connection(
            address,
            source_system=system_id,
            source_component=self.component_id,
            dialect="ardupilotmega",
        )
        #: The dialect module (message classes and constants).
        self.dialect: Any = mavutil.mavlink
        self._stopping = threading.Event()
        self._reader: threading.Thread | None = None

    def is_for_me(self, message: Any) -> bool:
        """Whether a received message is addressed to this vehicle's autopilot component."""
        return is_addressed_to(message, self.system_id, self.component_id)

    @property
    def mav(self) -> Any:
        """pymavlink's MAVLink object: ``mav.<message>_send(...)`` sends a message."""
        return self._connection.mav

    def start(self, on_message: Callable[[Any], None], loop: asyncio.AbstractEventLoop) -> None:
        """Hand every received message to ``on_message``, called in ``loop``."""

        def read() -> None:
            while not self._stopping.is_set():
                try:
                    message = self._connection.recv_match(blocking=True, timeout=_READ_TIMEOUT_S)
                except OSError as error:  # a TCP peer that went away: wait for the next one
                    logger.debug("MAVLink receive: %s", error)
                    self._stopping.wait(_READ_TIMEOUT_S)
                    continue
                if message is None or message.get_type() == "BAD_DATA":
                    continue
                try:
                    loop.call_soon_threadsafe(on_message, message)
                except RuntimeError:  # the loop closed
                    return

        self._reader = threading.Thread(target=read, name="rovlink-mavlink-reader", daemon=True)
        self._reader.start()

    def close(self) -> None:
        """Stop reading and close the socket."""
        self._stopping.set()
        if self._reader is not None:
            self._reader.join(timeout=2.0)
        self._connection.close()
