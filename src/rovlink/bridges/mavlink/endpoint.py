"""The MAVLink endpoint: a pymavlink connection (MAVLink 2, ArduPilot's dialect) whose received
messages reach the event loop.

pymavlink's connections block, so one reader thread waits on the socket and hands each message
to the loop; everything is sent from the loop. Nothing here packs bytes: pymavlink does.

Ground stations come and go, and the endpoint outlives them. pymavlink's TCP connections swap
their socket when a peer goes (a write that fails closes it), so reading and writing never run at
once: the reader waits for data outside the lock and reads under it. A TCP ground station that
closes its end is let go (``tcpin``: the next one is accepted; ``tcp``: it is dialled again),
where pymavlink would read an ended stream for ever; a ``tcp`` one not there yet when the bridge
starts is dialled until it answers, where pymavlink's client would give up.
"""

from __future__ import annotations

import asyncio
import os
import select
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
    "udpin": "listen for ground stations there, send to every one that has sent something",
    "tcpin": "listen for one ground station's TCP connection there",
    "tcp": "connect to a ground station's TCP server there",
}
_READ_TIMEOUT_S = 0.2  # how soon the reader thread notices it should stop
#: ``tcp``: how often a ground station's TCP server that went away is dialled again, s.
_REDIAL_S = 1.0
#: Messages whose target system field is not ``target_system`` (MANUAL_CONTROL's is ``target``).
_TARGET_SYSTEM_FIELD = {"MANUAL_CONTROL": "target"}
#: Messages taken only when aimed at this system, never as a broadcast: ArduSub takes a joystick
#: aimed at it only, so one broadcast cannot drive every vehicle on the network.
_AIMED_ONLY = frozenset({"MANUAL_CONTROL"})
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
    everyone, and one for another component of this system is not this component's. A joystick
    (MANUAL_CONTROL) must be aimed at this system, as ArduSub has it: a broadcast is not.
    """
    fields = message.get_fieldnames()
    kind = message.get_type()
    system_field = _TARGET_SYSTEM_FIELD.get(kind, "target_system")
    systems = (system_id,) if kind in _AIMED_ONLY else (_BROADCAST, system_id)
    if system_field in fields and getattr(message, system_field) not in systems:
        return False
    return "target_component" not in fields or message.target_component in (
        _BROADCAST,
        component_id,
    )


def _check_udp_port_free(host: str, port: int) -> None:
    """``OSError`` (address in use) if a UDP socket is bound at ``host:port`` already.

    pymavlink's UDP server binds with SO_REUSEADDR, with which Linux lets a second socket bind
    the same port beside one that has it too: a second bridge (or a ground station listening
    there) would start, and each ground station's datagrams, a disarm among them, would reach
    one of the two, whichever the kernel picked. A socket without the option may not share it.
    """
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind((host, port))


def _dial(address: tuple[str, int]) -> socket.socket | None:
    """A TCP connection to a ground station's server, ready for pymavlink; ``None`` if it does
    not answer within :data:`_REDIAL_S` (the next attempt is the reader's)."""
    try:
        port = socket.create_connection(address, timeout=_REDIAL_S)
    except OSError as error:
        logger.debug("MAVLink: tcp:%s:%s: %s", *address, error)
        return None
    port.setblocking(False)
    port.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return port


def _tcp_client(mavtcp: type[Any]) -> type[Any]:
    """pymavlink's TCP client class, made to start without its ground station.

    pymavlink's connects in its constructor, tries a few times (printing, sleeping, blocking for
    as long as a host that does not answer takes) and raises: a bridge started before its
    ground station (the vehicle's computer boots first) would end. This one tries once, for at
    most :data:`_REDIAL_S`, and is otherwise left unconnected (``port`` ``None``) for the
    endpoint's reader to dial.
    """

    class DialledLater(mavtcp):  # type: ignore[misc]
        def do_connect(self) -> None:
            port = _dial(self.destination_addr)
            # (pymavlink's constructor takes the descriptor of what this leaves in ``port``)
            self.port: socket.socket | None = socket.socket() if port is None else port
            self.dialled = port is not None

        def __init__(self, device: str, **options: Any) -> None:
            super().__init__(device, **options)
            if not self.dialled and self.port is not None:
                self.port.close()
                self.port = None
                logger.info("MAVLink: no ground station at tcp:%s yet: dialling it", device)

    return DialledLater


class MavlinkEndpoint:
    """One MAVLink connection as vehicle ``system_id``, component 1 (the autopilot)."""

    def __init__(self, address: str, *, system_id: int = 1) -> None:
        check_address(address)
        scheme, host, port = address.split(":")
        if scheme == "udpout":
            # pymavlink resolves an output's host only when it sends, and drops the error:
            # a name that does not resolve would be a bridge sending nowhere, silently.
            socket.getaddrinfo(host, int(port), type=socket.SOCK_DGRAM)
        if scheme == "udpin":
            _check_udp_port_free(host, int(port))
        # MAVLink 2 (pymavlink reads this when it loads a dialect): signatures aside, every
        # field of every message, and extensions such as SYS_STATUS's extended sensors.
        os.environ["MAVLINK20"] = "1"
        from pymavlink import mavutil  # noqa: PLC0415 - the mavlink extra loads only here

        self.address = address
        self.system_id = system_id
        self.component_id = 1
        if scheme == "tcp":
            mavutil.set_dialect("ardupilotmega")
            self._connection: Any = _tcp_client(mavutil.mavtcp)(
                f"{host}:{port}", source_system=system_id, source_component=self.component_id
            )
        else:
            self._connection = mavutil.mavlink_connection(
                address,
                source_system=system_id,
                source_component=self.component_id,
                dialect="ardupilotmega",
            )
        if scheme == "udpout":
            # A topside subnet's broadcast address is a destination as good as any (a ground
            # station whose address is not known beforehand): without this every send to it
            # fails, and pymavlink drops the error.
            self._connection.port.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        #: The dialect module (message classes and constants).
        self.dialect: Any = mavutil.mavlink
        self.scheme = scheme
        self._stopping = threading.Event()
        self._reader: threading.Thread | None = None
        # Sends (from the loop) and reads (from the reader thread) one at a time: pymavlink
        # closes and replaces a TCP socket in either when its peer has gone.
        self._lock = threading.Lock()
        send = self._connection.write

        def write(data: bytes) -> None:
            with self._lock:
                send(data)

        self._connection.write = write
        if scheme == "tcp":
            # pymavlink would only print that the server went away (to the bridge's output),
            # and keep the dead socket; the reader dials again instead.
            self._connection.handle_disconnect = self._connection.handle_eof = self._hang_up

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
                for message in self._receive():
                    try:
                        loop.call_soon_threadsafe(on_message, message)
                    except RuntimeError:  # the loop closed
                        return

        self._reader = threading.Thread(target=read, name="rovlink-mavlink-reader", daemon=True)
        self._reader.start()

    def _receive(self) -> list[Any]:
        """The messages that arrive within the read timeout (none if nothing does)."""
        connection = self._connection
        if self.scheme == "tcp" and connection.port is None:
            self._redial()
            return []
        try:
            ready, _, _ = select.select([connection.fd], [], [], _READ_TIMEOUT_S)
        except (OSError, ValueError):  # the socket was closed under us: the next one will do
            self._stopping.wait(_READ_TIMEOUT_S)
            return []
        if not ready:
            return []
        messages = []
        with self._lock:
            try:
                while (message := connection.recv_match(blocking=False)) is not None:
                    if message.get_type() != "BAD_DATA":
                        messages.append(message)
            except Exception as error:  # pymavlink on a socket that just went away (it may
                logger.debug("MAVLink receive: %s", error)  # raise more than OSError)
            self._let_go_of_an_ended_peer()
        return messages

    def _let_go_of_an_ended_peer(self) -> None:
        """A TCP ground station that closed its end: close ours (pymavlink reads it for ever)."""
        if self.scheme not in ("tcp", "tcpin"):
            return
        connection = self._connection
        port = connection.port
        if port is None:
            return
        try:
            ended = port.recv(1, socket.MSG_PEEK) == b""
        except BlockingIOError:
            return  # open, nothing to read
        except OSError:
            ended = True
        if not ended:
            return
        logger.info("MAVLink: the ground station at %s closed the connection", self.address)
        port.close()
        connection.port = None
        if self.scheme == "tcpin":
            connection.fd = connection.listen.fileno()  # accept the next one

    def _hang_up(self) -> None:
        """``tcp``: the ground station's server went away (called by pymavlink under the lock)."""
        port = self._connection.port
        if port is not None:
            logger.info("MAVLink: the ground station at %s closed the connection", self.address)
            port.close()
            self._connection.port = None

    def _redial(self) -> None:
        """``tcp``: connect to the ground station's server again (outside the lock: sends go
        nowhere meanwhile, as pymavlink's do while its socket is closed)."""
        if self._stopping.wait(_REDIAL_S):
            return
        connection = self._connection
        port = _dial(connection.destination_addr)
        if port is None:
            return
        with self._lock:
            connection.port = port
            connection.fd = port.fileno()
        logger.info("MAVLink: connected to the ground station at %s again", self.address)

    def close(self) -> None:
        """Stop reading and close the socket."""
        self._stopping.set()
        if self._reader is not None:
            self._reader.join(timeout=2.0)
        with self._lock:
            if self.scheme == "tcp" and self._connection.port is None:
                return  # (pymavlink's close would fail on the socket it has not got)
            self._connection.close()
