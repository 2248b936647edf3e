"""``rovlink fault``: a TCP port in front of any link, with faults, for programs in any language.

The proxy opens the controller's link once (a serial port that resets its board on opening is
opened one time only) and serves one TCP client at a time, as a serial port would. A second
client that connects meanwhile reads :data:`BUSY_MESSAGE` and is disconnected at once: nothing
it sends ever reaches the controller (a queued client's commands would run long after it sent
them, right after the safety ``#stop!``). A client that disconnects leaves the robot stopped:
the proxy sends ``#stop!`` to the controller, undamaged, and again on exit.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
import time
from collections.abc import Callable

from rovlink.busy_tcp import HUNG_UP_GRACE_S, RefusedClients, has_hung_up
from rovlink.client.errors import ConnectionLostError
from rovlink.faults.port import FaultPort
from rovlink.logs import get_logger

__all__ = ["BUSY_MESSAGE", "STOP_FRAME", "FaultProxy"]

logger = get_logger(__name__)

#: Sent to the controller when a client goes and when the proxy stops: a bare #stop! is honoured
#: in either checksum mode (P3).
STOP_FRAME = b"#stop!"
#: What a client reads when another one is being served (a text line, as the simulator's).
BUSY_MESSAGE = b"busy: the fault proxy already has a client\r\n"
_POLL_S = 0.05
#: How long serve() waits for its pump thread to see the end (a few of its reads).
_PUMP_JOIN_S = 2.0
_BACKLOG = 8


class FaultProxy:
    """Serve ``port`` (a :class:`FaultPort`) on a TCP listener, one client at a time.

    A client that connects while another is served reads :data:`BUSY_MESSAGE` and is
    disconnected; what it sent is read and dropped. A client that closed and connected again at
    once is served, after its first connection's ``#stop!``.
    """

    def __init__(self, port: FaultPort, host: str, tcp_port: int) -> None:
        self.port = port
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        listener = socket.socket(family, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((host, tcp_port))
            # A backlog so that a second client is accepted, and refused, at once: with
            # listen(1) the kernel queued it, its commands and all, until the first one left.
            listener.listen(_BACKLOG)
        except OSError:
            listener.close()
            raise
        listener.setblocking(False)
        self._listener = listener
        bound = listener.getsockname()
        self.address: tuple[str, int] = (bound[0], bound[1])
        # Only the thread in serve() uses the selector: the listener and refused clients.
        self._selector = selectors.DefaultSelector()
        self._selector.register(listener, selectors.EVENT_READ, None)
        self._refused = RefusedClients(self._selector, BUSY_MESSAGE)
        self._client: socket.socket | None = None
        self._client_lock = threading.Lock()
        #: The thread serving the current client; alive until its #stop! is sent.
        self._session: threading.Thread | None = None
        #: Set as the current client's #stop! is sent: the next client may be served. (Its
        #: thread may still be finishing meanwhile; a client that connected once the stop was
        #: on its way was refused or not at random.)
        self._session_over = threading.Event()
        self._session_over.set()
        #: Held for each write to the controller: the next client's bytes follow the #stop!.
        self._controller_lock = threading.Lock()
        self.clients_served = 0
        self.clients_refused = 0
        self.lost: str | None = None

    def serve(self, should_stop: Callable[[], bool]) -> None:
        """Accept clients and move bytes until ``should_stop()`` or the controller's link dies."""
        self.port.timeout = _POLL_S
        pump = threading.Thread(
            target=self._controller_to_client,
            args=(should_stop,),
            name="fault proxy pump",
            daemon=True,
        )
        pump.start()
        try:
            while not should_stop() and self.lost is None:
                for key, _ in self._selector.select(_POLL_S):
                    if key.fileobj is self._listener:
                        self._on_connection(should_stop)
                    else:
                        assert isinstance(key.fileobj, socket.socket)
                        self._refused.on_readable(key.fileobj)
                self._refused.expire(time.monotonic())
        finally:
            if self._session is not None:
                self._session.join()  # (it ends on should_stop() or a lost link, as this loop)
            # The pump too (it reads every _POLL_S): left reading, it would find the port
            # closed by the caller and report a clean exit as a lost link.
            pump.join(_PUMP_JOIN_S)
            self._refused.close()
            self._stop_robot()
            self._selector.close()
            self._listener.close()

    # -- clients -----------------------------------------------------------------------------

    def _on_connection(self, should_stop: Callable[[], bool]) -> None:
        try:
            connection, address = self._listener.accept()
        except (BlockingIOError, InterruptedError):
            return
        # Busy until the session's thread has sent its #stop!: a client that connected before
        # then is refused, never served after the stop with what it sent meanwhile. One that
        # came after the served client hung up (a program that closed and connected again at
        # once) waits for that stop instead.
        if not self._session_over.is_set() and self._client_has_hung_up():
            self._session_over.wait(HUNG_UP_GRACE_S)
        if not self._session_over.is_set():
            logger.info("refused %s:%s: busy", address[0], address[1])
            self.clients_refused += 1
            self._refused.refuse(connection)
            return
        logger.info("client %s:%s connected", address[0], address[1])
        self.clients_served += 1
        self._session_over.clear()
        self._session = threading.Thread(
            target=self._serve_client,
            args=(connection, address, should_stop),
            name="fault proxy client",
            daemon=True,
        )
        self._session.start()

    def _client_has_hung_up(self) -> bool:
        """Whether the client served has closed its end (or its session is ending)."""
        with self._client_lock:
            client = self._client
        return client is None or has_hung_up(client)

    def _serve_client(
        self,
        connection: socket.socket,
        address: tuple[str, int],
        should_stop: Callable[[], bool],
    ) -> None:
        connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        connection.settimeout(_POLL_S)
        with self._client_lock:
            self._client = connection
        try:
            self._client_to_controller(connection, should_stop)
        finally:
            with self._client_lock:
                self._client = None
            connection.close()
            with self._controller_lock:
                self._session_over.set()  # (the next client's bytes wait for this lock)
                self._stop_robot()
            logger.info("client %s:%s gone: #stop! sent", address[0], address[1])

    def _client_to_controller(
        self, connection: socket.socket, should_stop: Callable[[], bool]
    ) -> None:
        while not should_stop() and self.lost is None:
            try:
                data = connection.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            try:
                with self._controller_lock:
                    self.port.write(data)
            except ConnectionLostError as error:
                self.lost = str(error)
                return

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
