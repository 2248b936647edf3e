"""``rovlink fault``: a TCP port in front of any link, with faults, for programs in any language.

The proxy opens the controller's link once (a serial port that resets its board on opening is
opened one time only) and serves one TCP client at a time. A client that disconnects leaves the
robot stopped: the proxy sends ``#stop!`` to the controller, undamaged, and again on exit.
"""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Callable

from rovlink.client.errors import ConnectionLostError
from rovlink.faults.port import FaultPort
from rovlink.logs import get_logger

__all__ = ["STOP_FRAME", "FaultProxy"]

logger = get_logger(__name__)

#: Sent to the controller when a client goes and when the proxy stops: a bare #stop! is honoured
#: in either checksum mode (P3).
STOP_FRAME = b"#stop!"
_POLL_S = 0.05


class FaultProxy:
    """Serve ``port`` (a :class:`FaultPort`) on a TCP listener, one client at a time."""

    def __init__(self, port: FaultPort, host: str, tcp_port: int) -> None:
        self.port = port
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        listener = socket.socket(family, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((host, tcp_port))
            listener.listen(1)
        except OSError:
            listener.close()
            raise
        listener.settimeout(_POLL_S)
        self._listener = listener
        bound = listener.getsockname()
        self.address: tuple[str, int] = (bound[0], bound[1])
        self._client: socket.socket | None = None
        self._client_lock = threading.Lock()
        self.clients_served = 0
        self.lost: str | None = None

    def serve(self, should_stop: Callable[[], bool]) -> None:
        """Accept clients and move bytes until ``should_stop()`` or the controller's link dies."""
        self.port.timeout = _POLL_S
        pump = threading.Thread(target=self._controller_to_client, args=(should_stop,), daemon=True)
        pump.start()
        try:
            while not should_stop() and self.lost is None:
                try:
                    connection, address = self._listener.accept()
                except TimeoutError:
                    continue
                except OSError:  # pragma: no cover - the listener closed under us
                    break
                logger.info("client %s:%s connected", address[0], address[1])
                self.clients_served += 1
                self._serve_client(connection, should_stop)
                logger.info("client %s:%s gone: #stop! sent", address[0], address[1])
        finally:
            self._stop_robot()
            self._listener.close()

    def _serve_client(self, connection: socket.socket, should_stop: Callable[[], bool]) -> None:
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        connection.settimeout(_POLL_S)
        with self._client_lock:
            self._client = connection
        try:
            while not should_stop() and self.lost is None:
                try:
                    data = connection.recv(4096)
                except TimeoutError:
                    continue
                except OSError:
                    break
                if not data:
                    break
                try:
                    self.port.write(data)
                except ConnectionLostError as error:
                    self.lost = str(error)
                    break
        finally:
            with self._client_lock:
                self._client = None
            connection.close()
            self._stop_robot()

    def _controller_to_client(self, should_stop: Callable[[], bool]) -> None:
        while not should_stop() and self.lost is None:
            try:
                data = self.port.read(4096)
            except ConnectionLostError as error:
                self.lost = str(error)
                return
            if not data:
                continue
            with self._client_lock:
                client = self._client
                if client is None:
                    continue  # nobody listens: dropped, as on an unplugged line
                with contextlib.suppress(OSError):
                    client.sendall(data)

    def _stop_robot(self) -> None:
        try:
            self.port.send_clean(STOP_FRAME)
        except ConnectionLostError:
            logger.warning("could not send #stop!: the controller's link is lost")
