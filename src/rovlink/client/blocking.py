"""The blocking client: ``rovlink.connect(url)`` and one method per command of the protocol.

One reader thread per connection reads whatever the port has, feeds it to the
:class:`~rovlink.client.session.Session` (which matches replies to the queue of pending queries)
and wakes the callers whose queries it settled; it also sends keep-alive queries when the link
is idle and times out queries nobody waits for. Callers write under a lock, so the queue's order
is the wire's order and any number of threads may share one client.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import TypeVar

from rovlink.client import operations
from rovlink.client.counters import LinkCounters
from rovlink.client.errors import ConnectionLostError, QueryTimeoutError
from rovlink.client.links import Link, open_link
from rovlink.client.options import ClientOptions, StrayCallback
from rovlink.client.sensors import Sensors
from rovlink.client.session import Outcome, PendingQuery, Session
from rovlink.client.unsolicited import report
from rovlink.client.url import parse_url
from rovlink.protocol import Command, Response

__all__ = ["KEEPALIVE_QUERY", "Client", "connect"]

T = TypeVar("T")

#: The query sent when the link has been idle: any valid frame feeds the controller's watchdog
#: (P17), and a query also proves the controller is still answering.
KEEPALIVE_QUERY = Command("qd")
#: The reader looks around (deadlines, keep-alive, close) at least this often.
_MAX_READ_WAIT_S = 0.25


class Client:
    """A blocking connection to a controller; thread-safe. Make one with :func:`connect`.

    Example::

        with rovlink.connect("/dev/ttyUSB0") as rov:
            rov.start()
            rov.hold_depth(100)
            print(rov.sensors().depth_cm)
            rov.stop()
    """

    def __init__(
        self,
        link: Link,
        options: ClientOptions | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """Drive the controller on ``link`` (already open; the client closes it).

        Sends ``#crcon!`` or ``#crcoff!`` at once so the controller's checksum mode is the one
        asked for, whatever an earlier session left behind.

        Example::

            client = Client(open_link(parse_url("socket://localhost:5760")))
        """
        self._options = options or ClientOptions()
        self._link = link
        self._clock = clock
        self._session = Session(algorithm=self._options.algorithm,
                                timeout_s=self._options.timeout_s)
        self._state_lock = threading.Lock()  # the session and the lost/closed state
        self._wire_lock = threading.Lock()  # one writer at a time: queue order = wire order
        self._mode_lock = threading.Lock()  # held by queries; a checksum switch drains them
        self._lost: ConnectionLostError | None = None
        self._closing = False
        self._reader = threading.Thread(
            target=self._read_loop, name=f"rovlink reader ({link.description})", daemon=True
        )
        self._reader.start()
        try:
            self._send(operations.checksum(self._options.checksum))
        except BaseException:
            self.close()
            raise

    # -- the connection -------------------------------------------------------------------------

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if exc_type is not None and self._lost is None:
            # Leaving by an error: make the robot safe before letting go of it.
            with contextlib.suppress(ConnectionError):
                self.stop()
        self.close()

    def close(self) -> None:
        """Stop the reader and release the port; pending and later calls raise ConnectionLostError.

        Example::

            rov = rovlink.connect("sim://")
            rov.close()
        """
        with self._state_lock:
            if self._closing:
                return
            self._closing = True
        self._link.wake()
        if threading.current_thread() is not self._reader:
            self._reader.join(timeout=2.0)
        self._link.close()
        self._connection_lost(ConnectionLostError(f"{self._link.description}: closed"))

    @property
    def closed(self) -> bool:
        """Whether the client was closed or lost its connection.

        Example::

            if rov.closed: rov = rovlink.connect(url)
        """
        return self._closing or self._lost is not None

    @property
    def description(self) -> str:
        """What the client is connected to, e.g. ``tcp localhost:5760``.

        Example::

            print(f"connected to {rov.description}")
        """
        return self._link.description

    @property
    def checksum_enabled(self) -> bool:
        """Whether frames carry checksums now (see :meth:`set_checksum`).

        Example::

            assert rovlink.connect("sim://", checksum=True).checksum_enabled
        """
        return self._session.checksum_enabled

    @property
    def counters(self) -> LinkCounters:
        """A snapshot of the link's counters: frames, timeouts, retries, checksum errors, ….

        Example::

            print(rov.counters.timeouts, rov.counters.checksum_errors)
        """
        with self._state_lock:
            return self._session.counters.copy()

    # -- commands -------------------------------------------------------------------------------

    def stop(self) -> None:
        """``#stop!``: all motors off and motion locked (always honoured, even with a bad checksum).

        Example::

            rov.stop()
        """
        self._send(operations.STOP)

    def start(self) -> None:
        """``#start!``: unlock motion, with neutral set-points.

        Example::

            rov.start()
        """
        self._send(operations.START)

    def set_checksum(self, enabled: bool) -> None:
        """``#crcon!`` / ``#crcoff!``; the client's own encoder and decoder switch with it.

        Queries already on the wire are answered first, in the old mode.

        Example::

            rov.set_checksum(True)   # every frame now carries a CRC-8 (or the chosen algorithm)
        """
        command = operations.checksum(enabled)
        self._check_open()
        with self._mode_lock:
            self._drain()
            self._send(command)

    def set_debug(self, enabled: bool) -> None:
        """``#debug1!`` / ``#debug0!``: debug text goes to ``on_stray`` and logging.

        Example::

            rov.set_debug(True)
        """
        self._send(operations.debug(enabled))

    def set_max_pwm(self, duty: int) -> None:
        """``#mgmp.N!``: cap every thruster's PWM duty, 0–255.

        Example::

            rov.set_max_pwm(180)
        """
        self._send(operations.max_pwm(duty))

    def set_depth_pid(self, p: int | None = None, i: int | None = None,
                      d: int | None = None) -> None:
        """``#mvpdp.N!``, ``#mvpdi.N!``, ``#mvpidd.N!`` for each gain given (0–99 each).

        All gains are checked before any is sent.

        Example::

            rov.set_depth_pid(p=30, d=10)
        """
        for command in operations.depth_pid(p, i, d):
            self._send(command)

    def set_direct_mode(self, enabled: bool) -> None:
        """``#mvdirect.1!`` (vertical thrust set directly) or ``#mvdirect.0!`` (hold depth).

        Example::

            rov.set_direct_mode(True)
            rov.set_vertical_thrust(-30)
        """
        self._send(operations.direct_mode(enabled))

    def set_vertical_thrust(self, percent: int) -> None:
        """``#mvs.±N!``: vertical thrust in direct mode, −100…+100 %, + up.

        Example::

            rov.set_vertical_thrust(+50)
        """
        self._send(operations.vertical_thrust(percent))

    def hold_depth(self, depth_cm: int) -> None:
        """``#mvd.N!``: in depth mode, hold this depth, 0–9999 cm below the surface.

        Example::

            rov.hold_depth(100)   # one metre
        """
        self._send(operations.hold_depth(depth_cm))

    def move(self, direction_deg: int, power_percent: int) -> None:
        """``#th.A.P!``: move horizontally, direction 0–360° clockwise from the bow, power 0–100 %.

        Example::

            rov.move(270, 25)   # left at a quarter power
        """
        self._send(operations.move(direction_deg, power_percent))

    def set_depth_zero(self, raw: int) -> None:
        """``#sdz.N!``: the raw pressure reading at the surface, 0–1024.

        Example::

            rov.set_depth_zero(rov.pressure_raw())   # calibrate at the surface
        """
        self._send(operations.depth_zero(raw))

    def set_depth_scale(self, k: int) -> None:
        """``#sdk.N!``: the depth coefficient, depth[m] = (raw − zero) · k / 10000; 0–10000.

        Example::

            rov.set_depth_scale(1000)
        """
        self._send(operations.depth_scale(k))

    def reset_leak(self) -> None:
        """``#slreset!``: clear the leak latch.

        Example::

            rov.reset_leak()
        """
        self._send(operations.RESET_LEAK)

    def claw_open(self) -> None:
        """``#h+!``: run the claw motor one pulse towards open.

        Example::

            rov.claw_open()
        """
        self._send(operations.CLAW_OPEN)

    def claw_close(self) -> None:
        """``#h-!``: run the claw motor one pulse towards closed.

        Example::

            rov.claw_close()
        """
        self._send(operations.CLAW_CLOSE)

    # -- queries --------------------------------------------------------------------------------

    def depth_cm(self) -> int:
        """``#qd!``: depth below the surface, cm.

        Example::

            if rov.depth_cm() > 500: rov.hold_depth(400)
        """
        return self._ask(operations.DEPTH_CM)

    def pressure_raw(self) -> int:
        """``#qr!``: the raw pressure-sensor reading, 0–1024.

        Example::

            zero = rov.pressure_raw()
        """
        return self._ask(operations.PRESSURE_RAW)

    def leak_detected(self) -> bool:
        """``#q.l!``: whether the leak sensor fired since the last :meth:`reset_leak`.

        Example::

            if rov.leak_detected(): rov.hold_depth(0)
        """
        return self._ask(operations.LEAK_DETECTED)

    def roll_deg(self) -> int:
        """``#qro!``: roll, −90…+90°.

        Example::

            print(rov.roll_deg())
        """
        return self._ask(operations.ROLL_DEG)

    def pitch_deg(self) -> int:
        """``#qpi!``: pitch, −90…+90°.

        Example::

            print(rov.pitch_deg())
        """
        return self._ask(operations.PITCH_DEG)

    def heading_deg(self) -> int:
        """``#qhe!``: magnetic heading, 0–360°.

        Example::

            print(rov.heading_deg())
        """
        return self._ask(operations.HEADING_DEG)

    def sensors(self) -> Sensors:
        """``#qsa!``: every sensor at once.

        Example::

            reading = rov.sensors()
            print(reading.depth_cm, reading.heading_deg, reading.leak_detected)
        """
        return self._ask(operations.SENSORS)

    # -- any command ----------------------------------------------------------------------------

    def send(self, command: Command) -> tuple[Response, ...]:
        """Send any command of the table; a query returns its replies (retried like the others).

        Example::

            from rovlink.protocol import Command
            rov.send(Command("th", (90, 40)))
            (reply,) = rov.send(Command("qd"))
        """
        if command.name in ("crcon", "crcoff"):
            self.set_checksum(command.name == "crcon")
            return ()
        if command.spec.is_query:
            return self._request(command)
        self._send(command)
        return ()

    def send_raw(self, frame: str | bytes) -> tuple[Response, ...]:
        """Send a frame exactly as given, once; if it is a query, wait for and return its replies.

        For experiments: the frame is not checked or given a checksum, and is not retried.

        Example::

            rov.send_raw("#qd!")       # → (Response(name='qd', values=(57,)),)
            rov.send_raw(b"#bogus!")   # the controller drops it (see its debug output)
        """
        data = operations.raw_frame(frame)
        if data in (b"#crcon!", b"#crcoff!"):
            self.set_checksum(data == b"#crcon!")
            return ()
        self._check_open()
        with self._mode_lock, self._wire_lock:
            with self._state_lock:
                pending = self._session.raw(data, self._clock())
                if pending is not None:
                    pending.waiter = threading.Event()
            self._write(data)
        if pending is None:
            return ()
        outcome = self._wait(pending)
        if outcome is Outcome.ANSWERED:
            return tuple(pending.responses)
        if outcome is Outcome.DISCONNECTED:
            raise self._lost_error()
        raise QueryTimeoutError(pending.command, [outcome.value], self._options.timeout_s)

    # -- internals ------------------------------------------------------------------------------

    def _check_open(self) -> None:
        if self._lost is not None:
            raise self._lost_error()

    def _lost_error(self) -> ConnectionLostError:
        lost = self._lost
        reason = str(lost) if lost is not None else "closed"
        error = ConnectionLostError(f"connection lost: {reason}")
        error.__cause__ = lost
        return error

    def _connection_lost(self, error: ConnectionLostError) -> None:
        with self._state_lock:
            if self._lost is not None:
                return
            self._lost = error
            settled = self._session.disconnect()
        self._wake(settled)

    @staticmethod
    def _wake(settled: list[PendingQuery]) -> None:
        for query in settled:
            if isinstance(query.waiter, threading.Event):
                query.waiter.set()

    def _write(self, data: bytes) -> None:
        """Write under the wire lock; a failure is a lost connection."""
        try:
            self._link.write(data)
        except ConnectionLostError as error:
            self._connection_lost(error)
            raise self._lost_error() from error

    def _send(self, command: Command) -> None:
        self._check_open()
        with self._wire_lock:
            with self._state_lock:
                data = self._session.command(command, self._clock())
            self._write(data)

    def _ask(self, query: operations.Query[T]) -> T:
        return query.read(self._request(query.command))

    def _request(self, command: Command) -> tuple[Response, ...]:
        if threading.current_thread() is self._reader:
            raise RuntimeError("a query from an on_stray callback would wait for itself")
        failures: list[str] = []
        for attempt in range(self._options.retries + 1):
            pending = self._send_query(command, retry=attempt > 0)
            outcome = self._wait(pending)
            if outcome is Outcome.ANSWERED:
                return tuple(pending.responses)
            if outcome is Outcome.DISCONNECTED:
                raise self._lost_error()
            failures.append(outcome.value)
        raise QueryTimeoutError(command, failures, self._options.timeout_s)

    def _send_query(self, command: Command, *, retry: bool = False,
                    keepalive: bool = False) -> PendingQuery:
        self._check_open()
        with self._mode_lock, self._wire_lock:
            with self._state_lock:
                if retry:
                    self._session.counters.retries += 1
                data, pending = self._session.query(command, self._clock(), keepalive=keepalive)
                pending.waiter = threading.Event()
            self._write(data)
        return pending

    def _wait(self, pending: PendingQuery) -> Outcome:
        """Wait until the attempt settles; time it (and any older ones) out when due."""
        event = pending.waiter
        assert isinstance(event, threading.Event)
        while True:
            with self._state_lock:
                if pending.settled:
                    return pending.outcome
                now = self._clock()
                remaining = self._session.deadline(pending) - now
                if remaining <= 0:
                    expired = self._session.expire(now)
                    self._wake(expired)
                    continue
            event.wait(remaining)

    def _drain(self) -> None:
        """Wait for every query on the wire to settle (callers hold the mode lock)."""
        with self._state_lock:
            pending = self._session.pending
        for query in pending:
            self._wait(query)

    def _read_loop(self) -> None:
        while not self._closing:
            try:
                wait_s = self._housekeeping()
                data = self._link.read_available(wait_s)
            except ConnectionLostError as error:
                if not self._closing:
                    self._connection_lost(error)
                return
            if not data:
                continue
            with self._state_lock:
                received = self._session.receive(data, self._clock())
            self._wake(received.settled)
            if received.unsolicited:
                report(received.unsolicited, self._options.on_stray)

    def _housekeeping(self) -> float:
        """Time out overdue queries, keep the link alive; how long the reader may block now."""
        now = self._clock()
        with self._state_lock:
            expired = self._session.expire(now)
            next_deadline = self._session.next_deadline()
            last_sent_at = self._session.last_sent_at
        self._wake(expired)
        wait_s = _MAX_READ_WAIT_S
        if next_deadline is not None:
            wait_s = min(wait_s, next_deadline - now)
        keepalive_s = self._options.keepalive_s
        if keepalive_s and self._lost is None:
            idle_s = now - last_sent_at
            if idle_s >= keepalive_s and self._send_keepalive():
                idle_s = 0.0
            wait_s = min(wait_s, keepalive_s - idle_s)
        return max(wait_s, 0.001)

    def _send_keepalive(self) -> bool:
        # A checksum switch holds the mode lock while it drains: it is talking anyway.
        if not self._mode_lock.acquire(blocking=False):
            return False
        try:
            with self._wire_lock:
                with self._state_lock:
                    data, pending = self._session.query(
                        KEEPALIVE_QUERY, self._clock(), keepalive=True
                    )
                    pending.waiter = threading.Event()
                self._write(data)
        finally:
            self._mode_lock.release()
        return True


def connect(
    url: str,
    *,
    timeout: float = 0.5,
    retries: int = 2,
    checksum: bool = False,
    algorithm: str = "crc8",
    keepalive: float | None = 1.0,
    baudrate: int | None = None,
    on_stray: StrayCallback | None = None,
) -> Client:
    """Connect to a controller and return a blocking :class:`Client` (a context manager).

    ``url``: a serial device or pseudo-terminal path, any pyserial URL (``socket://host:port``,
    ``loop://``, ``rfc2217://…``) with ``?baudrate=`` or ``baudrate`` (default 115200), or
    ``sim://`` for a simulated controller in this process (``sim://?leak_at=5&seed=1``).
    ``timeout`` (s) per query attempt; ``retries`` more attempts of a query after a timeout or a
    corrupt reply; ``checksum`` and ``algorithm`` (``crc8``, ``xor``, ``sum8``) the mode to put
    the controller in; ``keepalive`` (s) of idle link before a keep-alive query (``None``: never);
    ``on_stray`` is called (in the reader thread) with debug text and frames nobody asked for.

    Example::

        import rovlink

        with rovlink.connect("/dev/ttyUSB0", checksum=True) as rov:
            rov.start()
            rov.move(0, 50)
            print(rov.sensors())
            rov.stop()
    """
    options = ClientOptions(timeout, retries, checksum, algorithm, keepalive, on_stray)
    link = open_link(parse_url(url, baudrate))
    try:
        return Client(link, options)
    except BaseException:
        link.close()
        raise
