"""The asyncio client: ``rovlink.aio.connect(url)``, the blocking client's methods as coroutines.

Native asyncio, not the blocking client in a thread: the event loop reads the port (see
:mod:`rovlink.aio.transport`), feeds the shared :class:`~rovlink.client.session.Session` and
resolves one future per query, so any number of queries can be in flight at once — their
replies are matched in order — and polling pipelines up to the line rate without a thread hop
per reply. Timeouts are one loop timer at the oldest query's deadline.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from asyncio.events import _get_running_loop as _running_loop  # (None, not an error, if none)
from collections import deque
from collections.abc import AsyncIterator, Callable, Coroutine, Generator
from types import TracebackType
from typing import TYPE_CHECKING, Any, TypeVar

from rovlink.aio.command_methods import AsyncCommandMethods
from rovlink.aio.slots import InFlightSlots, check_max_in_flight
from rovlink.aio.transport import ByteTransport, transport_for
from rovlink.aio.wakeup import wait_for_event
from rovlink.client import links, operations
from rovlink.client.counters import LinkCounters
from rovlink.client.errors import (
    ConnectionLostError,
    QueryTimeoutError,
    checksum_mode_unconfirmed,
)
from rovlink.client.events import EventCallback, subscriber
from rovlink.client.links import Link, SocketLink, open_link
from rovlink.client.options import (
    DEFAULT_BOOT_TIMEOUT_S,
    DEFAULT_MOTION_TIMEOUT_S,
    ClientOptions,
    StrayCallback,
    connect_options,
)
from rovlink.client.port_closing import close_within
from rovlink.client.readiness import ReadinessProbe
from rovlink.client.reconnection import (
    FailedAttempts,
    reconnect_delays_s,
    reconnecting_failed,
)
from rovlink.client.sensors import Sensors
from rovlink.client.session import Outcome, PendingQuery, Session
from rovlink.client.stop_at_exit import stop_at_exit, stop_within
from rovlink.client.unsolicited import DropLog, HookFailureLog, deliver
from rovlink.client.url import parse_url
from rovlink.logs import get_logger
from rovlink.protocol import Command, Response, Setting
from rovlink.protocol.frames import checksum_mode_frame

__all__ = ["DEFAULT_MAX_IN_FLIGHT", "AsyncClient", "connect"]

T = TypeVar("T")
logger = get_logger("rovlink.aio")

#: Queries on the wire at once: enough to keep a serial line busy, few enough for a small
#: controller's receive buffer (8 × ``#qsa!`` is 40 bytes).
DEFAULT_MAX_IN_FLIGHT = 8


# A plain name for the member tested per query: an enum member costs a descriptor call.
_ANSWERED = Outcome.ANSWERED
_Future = asyncio.Future  # (a global: no attribute lookup per reply)


class AsyncClient(AsyncCommandMethods):
    """An asyncio connection to a controller. Make one with :func:`connect`.

    Example::

        async with rovlink.aio.connect("sim://") as rov:
            await rov.start()
            depth, heading = await asyncio.gather(rov.depth_cm(), rov.heading_deg())
            async for reading in rov.telemetry(10):
                print(reading.depth_cm)
    """

    def __init__(
        self,
        link: Link,
        options: ClientOptions | None = None,
        *,
        max_in_flight: int = DEFAULT_MAX_IN_FLIGHT,
        reopen: Callable[[], Link] | None = None,
    ) -> None:
        """Wrap an open link; call :meth:`open` (``connect`` does) before use.

        With ``options.reconnect``, ``reopen`` opens the same port again after the link is lost.

        Example::

            client = AsyncClient(open_link(parse_url("socket://localhost:5760")))
            await client.open()
        """
        check_max_in_flight(max_in_flight)
        self._options = options or ClientOptions()
        self._link = link
        self._loop = asyncio.get_running_loop()
        self._clock = _loop_clock(self._loop)
        self._transport: ByteTransport = transport_for(link, self._loop)
        options = self._options
        self._session = Session(
            algorithm=options.algorithm,
            timeout_s=options.timeout_s,
            keepalive_s=options.keepalive_s,
            motion_timeout_s=options.motion_timeout_s,
            record_events=options.on_event is not None,
        )
        self._drops = DropLog()
        self._hook_failures = HookFailureLog()
        self._subscribers: list[EventCallback] = []
        # Events are being handed to the callbacks: a callback that makes more (a stop(), a
        # close() started as an eager task) has them delivered when it returns, not inside it.
        self._delivering = False
        self._probe: ReadinessProbe | None = None  # while waiting for the controller (P21)
        self._probe_data = asyncio.Event()
        self._in_flight = InFlightSlots(max_in_flight)
        self._max_in_flight = max_in_flight
        self._mode_settled = asyncio.Event()  # cleared while a checksum switch drains
        self._mode_settled.set()
        self._switching_mode = False  # (not self._mode_settled.is_set(), without a call)
        self._settled = asyncio.Event()  # set when the session settles anything, while watched
        self._settles_watched = 0  # how many wait on self._settled (close, a mode switch)
        self._timer: asyncio.TimerHandle | None = None
        self._timer_at = math.inf  # when self._timer fires (without calling its when())
        self._lost: ConnectionLostError | None = None
        self._closed = False
        self._in_forked_child = False  # (see _forked)
        self._reopen = reopen if self._options.reconnect else None
        self._link_ready = asyncio.Event()  # cleared while a lost link is being reopened
        self._link_ready.set()
        self._link_down = False  # (not self._link_ready.is_set(), without a call)
        self._reconnector: asyncio.Task[None] | None = None
        # Why the reopened link failed before it was ready (it fails that attempt).
        self._attempt_lost: ConnectionLostError | None = None
        self._released = asyncio.Event()  # set once close() has released the port
        # Once open() has succeeded: only a connection made is reopened when lost (a link lost
        # while connecting fails the connect, as the blocking client's does).
        self._opened = False

    async def open(self) -> AsyncClient:
        """Start reading, wait until the controller answers (``boot_timeout``, P21), and put it in
        the checksum mode asked for.

        Example::

            rov = await AsyncClient(link).open()
        """
        self._transport.start(self._on_data, self._on_lost)
        options = self._options
        try:
            await self._await_ready()
            # The mode frame is the driver's own (a replay of a recording leaves it out).
            self._send(operations.checksum(options.checksum), by_session=True)
            if options.checksum and options.boot_timeout_s is not None:
                self._session.reset_notices = False  # (the error below says what timeouts mean)
                self._session.own_queries = True
                try:
                    await self._request(Command("qd"))
                except QueryTimeoutError as error:
                    raise checksum_mode_unconfirmed(
                        self._link.description, options.algorithm, error
                    ) from error
                finally:
                    self._session.reset_notices = True
                    self._session.own_queries = False
        except BaseException:
            # A failed or cancelled open leaves nothing behind: the loop would go on watching a
            # descriptor the caller then closes, and the next port opened under that number
            # would never be read (and a timer would fire into a dead client).
            self._closed = True
            await self._release("open failed")
            raise
        self._opened = True
        self._arm_timer()
        stop_at_exit(self)  # (the robot it moved is stopped if the program ends with it open)
        return self

    async def _await_ready(self, *, reconnecting: bool = False) -> None:
        boot_timeout_s = self._options.boot_timeout_s
        if boot_timeout_s is None:
            return
        loop = self._loop
        probe = self._probe = ReadinessProbe(loop.time(), boot_timeout_s)
        try:
            while not probe.done(loop.time()):
                if self._closed or (self._lost is not None and not reconnecting):
                    if self._lost is not None:  # (the link's own error, as the blocking client)
                        raise probe.lost(self._lost)
                    raise self._lost_error()
                if reconnecting and self._attempt_lost is not None:
                    raise self._attempt_lost
                now = loop.time()
                if probe.timed_out(now):
                    raise probe.no_answer(
                        self._link.description, network=isinstance(self._link, SocketLink)
                    )
                data = probe.bytes_to_send(now)
                if data:
                    # (A write that finds the link lost is said at the top of the loop: as a
                    # failure to connect, with what the controller said before.)
                    with contextlib.suppress(ConnectionLostError):
                        self._write(data)
                        self._session.count_outside(now, sent=data)
                self._probe_data.clear()
                await wait_for_event(self._probe_data, max(probe.wait_s(loop.time()), 0.001))
        finally:
            self._probe = None

    # -- the connection -------------------------------------------------------------------------

    async def __aenter__(self) -> AsyncClient:
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if exc_type is not None and self._lost is None:
            # Leaving by an error: make the robot safe first (also while another task's close()
            # lets the queries on the wire be answered: the port is open until it ends).
            with contextlib.suppress(ConnectionError):
                await self.stop()
        await self.close()

    async def close(self) -> None:
        """Release the port; pending and later calls raise ConnectionLostError.

        If the program moved the robot or unlocked its motors since its last ``stop()``, and the
        link is up, ``#stop!`` goes out first, behind what was already queued for the port
        (``stop_on_close=False`` leaves the robot as it is); closing waits at most 2 s for the
        port to take it. Queries already on the wire are answered next (for at most
        ``timeout``): otherwise their replies — of keep-alives, of the polls of a ``telemetry``
        loop just left — would greet the next connection to the controller as if they answered
        its queries.

        Called in a later event loop than the one the client was opened in, once that one has
        been closed (``rov = asyncio.run(connect(url))``), it just closes the port: nothing
        could be answered.

        Example::

            await rov.close()
        """
        if self._in_forked_child:  # the port is the parent's: nothing to write or close
            return
        if _running_loop() is not self._loop:
            if not self._loop.is_closed():
                raise self._wrong_loop_error()
            self._close_after_its_loop()
            return
        stop_at_exit(self, wanted=False)
        if self._closed:
            await self._released.wait()  # a close() under way: return once it is done
            return
        # A robot driver sends zero on shutdown: a program that moved the robot and then
        # closed (or left ``async with``) left it driving until the controller's link-loss
        # watchdog (P17). Not on a link being reopened: nothing could carry it.
        stop_due = self._stop_due_on_close()
        self._closed = True
        self._link_ready.set()  # callers waiting for a reconnection fail now, as closed
        self._link_down = False
        if self._reconnector is not None:
            self._reconnector.cancel()
        try:
            if stop_due:
                with contextlib.suppress(ConnectionError):  # (lost as it was written)
                    self._send(operations.STOP, by_session=True)
            await self._drain()
        finally:
            # Also when the drain is cancelled (asyncio.timeout, a TaskGroup): otherwise the port
            # and the timer would outlive the client, and a second close() would do nothing.
            await self._release("closed")

    async def _release(self, why: str) -> None:
        """Settle every query, stop the timer and close the port (once ``_closed`` is set)."""
        try:
            self._on_lost(ConnectionLostError(f"{self._link.description}: {why}"))
            await self._transport.close()
        finally:
            self._released.set()

    def __repr__(self) -> str:
        """What it is connected to and whether the link is up: ``print(rov)`` in a program.

        Example::

            print(rov)  # <rovlink.aio.AsyncClient tcp 192.168.2.2:5760: open>
        """
        if self._closed:
            state = "closed"
        elif self._lost is not None:
            state = "lost"
        else:
            state = "reconnecting" if self._link_down else "open"
        return f"<rovlink.aio.AsyncClient {self._link.description}: {state}>"

    @property
    def closed(self) -> bool:
        """Whether the client was closed or lost its connection.

        Example::

            if rov.closed: rov = await rovlink.aio.connect(url)
        """
        return self._closed or self._lost is not None

    @property
    def description(self) -> str:
        """What the client is connected to.

        Example::

            print(rov.description)
        """
        return self._link.description

    @property
    def checksum_enabled(self) -> bool:
        """Whether frames carry checksums now.

        Example::

            print(rov.checksum_enabled)
        """
        return self._session.checksum_enabled

    def emergency_stop(self) -> bool:
        """Write ``#stop!`` to the port now, from any thread, without the event loop: for a
        program that is ending while its loop may be blocked (a dashboard whose terminal hung
        up). The session does not see the frame (no event, not counted); a frame the loop was
        writing may be cut by it, and the controller resynchronises on ``#`` (P1), so the
        ``#stop!`` still arrives whole. Whether it was written (not on a closed link).

        What the loop had queued for the port and not yet written (a ``start()`` behind a line
        slow to take it) goes out after this ``#stop!`` if the loop runs again: so the loop is
        also asked to :meth:`stop` as soon as it can, which follows whatever it queued.

        Called in the event loop itself (a signal handler of the loop, a callback), it never
        blocks the loop: the ``#stop!`` is written at once as far as the port takes it, ahead
        of everything queued, and the rest of it goes first when the port has room (``True``:
        written or first in line); the :meth:`stop` behind what was queued follows as the loop's
        next callback.

        Example::

            threading.Thread(target=rov.emergency_stop).start()
        """
        if self._lost is not None:  # (the port is open until close() has let the wire settle)
            return False
        if _running_loop() is self._loop:
            # A write to the port here would block the loop (up to the write timeout, on a line
            # with no room): ahead of the transport's queue instead, then the loop's own stop.
            # The stop behind what was queued is the loop's next callback, not made here: a
            # handler of signal.signal may have interrupted the client halfway through a call.
            self._loop.call_soon(self._stop_after_emergency)
            try:
                self._transport.write_first(self._session.frame_for(operations.STOP))
            except ConnectionLostError:  # (a link being reopened gets that stop first)
                return False
            return True
        with contextlib.suppress(RuntimeError):  # (the loop is closed: it writes nothing more)
            self._loop.call_soon_threadsafe(self._stop_after_emergency)
        try:
            self._link.write(self._session.frame_for(operations.STOP))
        except (ConnectionError, OSError):
            return False
        return True

    def _stop_at_exit(self) -> None:
        """The program ends with the client open (``asyncio.run`` returned without a close):
        the ``#stop!`` of close(), if due, written as :meth:`emergency_stop` writes it (the loop
        has ended), waited for at most 0.5 s: a line that takes nothing would hold the exit up
        for the write timeout."""
        if not self._closed and self._stop_due_on_close():
            stop_within(self.emergency_stop, self._link.description)

    def _forked(self, error: ConnectionLostError) -> None:
        """In a child made with ``os.fork()``: every call raises ``error`` (``stop()`` and
        :meth:`emergency_stop` write nothing), and close() neither writes nor closes the port,
        the parent's."""
        self._in_forked_child = True
        self._closed = True
        self._lost = error

    def _stop_due_on_close(self) -> bool:
        """Whether letting go of the robot owes it a ``#stop!``: the program moved it or
        unlocked it since its last stop, did not opt out, and a link can carry it."""
        return (
            self._options.stop_on_close
            and self._session.moved_since_stop
            and self._lost is None
            and not self._link_down
        )

    def _stop_after_emergency(self) -> None:
        """:meth:`stop` in the loop after :meth:`emergency_stop`, behind what it had queued."""
        if self._lost is not None:
            return
        with contextlib.suppress(ConnectionError):  # (lost meanwhile: nothing to stop on)
            self._send(operations.STOP)

    def frame_for(self, command: Command) -> bytes:
        """The bytes this client writes for ``command`` now: checksummed in checksum mode,
        ``#stop!`` always bare (P3).

        Example::

            rov.frame_for(Command("qd"))  # b"#qd!", or b"#qd8C!" in checksum mode
        """
        return self._session.frame_for(command)

    @property
    def counters(self) -> LinkCounters:
        """A snapshot of the link's counters.

        Example::

            print(rov.counters.retries)
        """
        return self._session.counters.copy()

    # -- commands: see command_methods (generated) ------------------------------------------

    async def telemetry(self, rate_hz: float | None = 10.0) -> AsyncIterator[Sensors]:
        """Poll :meth:`sensors` at ``rate_hz`` (``None``: as fast as the link allows), in order.

        Polls are pipelined (up to ``max_in_flight``), so a slow line does not lower the rate
        below what it can carry. A poll that times out is logged and skipped; a lost connection
        ends the iteration with ConnectionLostError.

        Example::

            async for reading in rov.telemetry(20):
                if reading.leak_detected:
                    break
        """
        # (A wrong type is a TypeError, a value out of range a ValueError, as for the settings.)
        if rate_hz is not None and (
            isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float)
        ):
            raise TypeError(
                f"telemetry: rate_hz must be a positive number or None, got {rate_hz!r}"
            )
        if rate_hz is not None and not (0 < rate_hz < math.inf):
            raise ValueError(
                f"telemetry: rate_hz must be a positive number or None, got {rate_hz!r}"
            )
        self._check_loop()
        period_s = 1.0 / rate_hz if rate_hz else 0.0
        loop = self._loop
        polls: deque[asyncio.Task[Sensors]] = deque()
        next_poll_at = loop.time()
        try:
            while True:
                now = loop.time()
                while len(polls) < self._max_in_flight and now >= next_poll_at:
                    polls.append(loop.create_task(self.sensors()))
                    # After a stall, carry on at the rate rather than catching up in a burst.
                    next_poll_at = max(next_poll_at + period_s, now - period_s) if period_s else now
                if polls and polls[0].done():
                    poll = polls.popleft()
                    try:
                        yield poll.result()
                    except QueryTimeoutError as error:
                        logger.warning("telemetry: skipped a reading: %s", error)
                    continue
                wait_s = next_poll_at - now if len(polls) < self._max_in_flight else None
                if polls:
                    await asyncio.wait({polls[0]}, timeout=wait_s)
                elif wait_s:
                    await asyncio.sleep(wait_s)
        finally:
            for poll in polls:
                poll.cancel()

    # -- any command ----------------------------------------------------------------------------

    async def send(self, command: Command) -> tuple[Response, ...]:
        """Send any command; a query returns its replies (retried like the others).

        Example::

            (reply,) = await rov.send(Command("qhe"))
        """
        command = operations.any_command(command)
        setting = command.setting
        if setting is not None and setting[0] is Setting.CHECKSUM:
            await self.set_checksum(setting[1])
            return ()
        if command.spec.is_query:
            return tuple(await self._request(command))
        if command == operations.STOP:
            self._send(command)  # (never waits for the line)
        else:
            await self._send_paced(command)  # as the command methods' frames
        return ()

    async def send_raw(self, frame: str | bytes) -> tuple[Response, ...]:
        """Send a frame exactly as given, once; a query returns its replies. One command frame
        at a time (ValueError for more); text or broken frames around it go as they are. On a
        slow serial line it waits for the line as a command method does, but for a query and a
        ``#stop!`` (which, as :meth:`stop`, supersedes a motion frame still waiting).

        Example::

            replies = await rov.send_raw("#qsa!")
        """
        self._check_loop()
        data = operations.raw_frame(frame)
        mode = checksum_mode_frame(data)
        if mode is not None:  # a mode frame by exact match, as the controller takes it (P3)
            await self.set_checksum(mode)
            return ()
        # As the command it carries: a query waits for a link being reopened (at most timeout)
        # and for a max_in_flight slot; a set command fails at once on a link being reopened.
        # (ValueError for more than one command, before anything waits.)
        command = self._session.raw_command(data)
        is_query = command is not None and command.spec.is_query
        if self._link_down and is_query:
            await self._await_link()
        self._check_open()
        # A frame that moves or unlocks, still waiting for a checksum switch or the line when a
        # stop() is called, is superseded by it (SupersededByStopError): it would follow the
        # #stop!. A raw #stop! is one such stop, and never waits for the line.
        stop = command == operations.STOP
        if stop:
            self._session.stop_asked()
        stops_seen = self._session.stops_asked
        if not is_query and not stop:
            await self._wait_for_line()  # as a command method's frame
            self._check_open()
        if is_query:
            await self._in_flight.take()  # (cancelled while it waits: it holds none)
        slot_handed_over = False
        try:
            while not self._mode_settled.is_set():  # (another switch may start as one ends)
                await self._mode_settled.wait()
            self._check_open()  # the link may have gone meanwhile: nothing would settle it
            data, pending = self._session.raw(data, self._clock(), stops_seen=stops_seen)
            if pending is not None:
                pending.waiter = self._loop.create_future()
                self._arm_timer()
            self._write(data)
            self._emit()
            if pending is None:
                return ()
            try:
                outcome: Outcome = await pending.waiter  # type: ignore[misc]
            except asyncio.CancelledError:
                if is_query and not pending.settled:  # on the wire: as _ask's
                    self._hold_slot_until_settled(pending)
                    slot_handed_over = True
                raise
        finally:
            if is_query and not slot_handed_over:
                self._in_flight.release()
        if outcome is Outcome.DISCONNECTED:
            raise self._lost_error()
        if outcome is Outcome.ANSWERED:
            return tuple(pending.responses)
        raise QueryTimeoutError(
            pending.command, [outcome.value], self._options.timeout_s, self._link.description
        )

    # -- internals ------------------------------------------------------------------------------

    async def _switch_checksum(self, command: Command) -> None:
        """Send ``#crcon!``/``#crcoff!`` once the queries on the wire are answered in the old
        mode."""
        self._check_loop()
        self._check_open()
        while not self._mode_settled.is_set():
            await self._mode_settled.wait()
        self._mode_settled.clear()
        self._switching_mode = True
        try:
            # Each query on the wire is answered, or times out, in the old mode.
            await self._wait_settled(self._session.pending, None)
            self._send(command)
        finally:
            self._mode_settled.set()
            self._switching_mode = False

    def _check_loop(self) -> None:
        if _running_loop() is not self._loop:
            raise self._wrong_loop_error()

    def _wrong_loop_error(self) -> Exception:
        # Its futures, timer and port watch are the loop's it was opened in: used from another
        # loop, a query was written from the wrong thread and then failed with asyncio's "got
        # Future attached to a different loop", its slot given back while it was on the wire.
        if self._closed or self._lost is not None:  # (as in its own loop)
            return self._lost_error()
        return RuntimeError(
            f"{self._link.description}: this client belongs to the event loop it was opened "
            "in, not this one (another thread's, or a later asyncio.run): call it in that "
            "loop (asyncio.run_coroutine_threadsafe from another thread; emergency_stop() "
            "from any thread), or connect again in this one"
        )

    def _close_after_its_loop(self) -> None:
        """close() once the client's loop is closed: nothing runs there any more (no reader, no
        timer), so the port is closed as it is, after the ``#stop!`` of close() if it is due
        (written as :meth:`emergency_stop` writes it); there was no other way to release it."""
        self._stop_at_exit()
        stop_at_exit(self, wanted=False)
        self._closed = True
        if self._lost is None:
            self._lost = ConnectionLostError(f"{self._link.description}: closed")
        with contextlib.suppress(OSError):  # (its reading thread, if any, ends on the closed port)
            close_within(self._link)  # (a close that hangs is reported and left to end)
        with contextlib.suppress(RuntimeError):  # (a waiter of the closed loop cannot be woken)
            self._released.set()

    def _stop_from_another_loop(self) -> None:
        """``stop()`` called in another event loop: the robot is stopped all the same, as
        :meth:`emergency_stop` does (written at once, then a stop in the client's own loop if it
        still runs). ConnectionLostError once the port is closed, as in the client's loop."""
        if not self.emergency_stop() and self._lost is not None:
            raise self._lost_error()

    def _check_open(self) -> None:
        if self._lost is not None or self._closed:
            raise self._lost_error()
        if self._link_down:  # a set command is not kept to be sent later
            raise ConnectionLostError(
                f"connection lost: {self._link.description}: lost, reconnecting"
            )

    async def _await_link(self) -> None:
        """While a lost link is being reopened, wait for it, at most ``timeout``."""
        if self._link_ready.is_set():
            return
        timeout_s = self._options.timeout_s
        await wait_for_event(self._link_ready, timeout_s)
        if not self._link_ready.is_set():
            raise ConnectionLostError(
                f"connection lost: {self._link.description}: not reopened within "
                f"{timeout_s:g} s (reconnecting)"
            )

    async def _drain(self) -> None:
        """Wait (at most ``timeout``) for the queries on the wire to settle."""
        await self._wait_settled(self._session.pending, self._options.timeout_s)

    async def _wait_settled(
        self, queries: tuple[PendingQuery, ...], timeout_s: float | None
    ) -> None:
        """Wait until every one of ``queries`` has settled, or ``timeout_s`` has passed.

        Their callers' futures are no guide: a caller may have been cancelled (the polls of a
        ``telemetry`` loop that was left are) while its query is still on the wire.
        """
        deadline = None if timeout_s is None else self._clock() + timeout_s
        while self._lost is None and any(not query.settled for query in queries):
            remaining = None if deadline is None else deadline - self._clock()
            if remaining is not None and remaining <= 0:
                return
            self._settled.clear()
            self._settles_watched += 1
            try:
                await wait_for_event(self._settled, remaining)  # (then looks again)
            finally:
                self._settles_watched -= 1

    def _lost_error(self) -> ConnectionLostError:
        lost = self._lost
        reason = str(lost) if lost is not None else f"{self._link.description}: closed"
        if lost is None and self._link_down and not self._closed:
            reason = f"{self._link.description}: lost, reconnecting"
        error = ConnectionLostError(f"connection lost: {reason}")
        error.__cause__ = lost
        return error

    def _write(self, data: bytes) -> None:
        try:
            self._transport.write(data)
        except ConnectionLostError as error:
            self._on_lost(error)
            raise self._lost_error() from error

    async def _send_paced(self, command: Command) -> None:
        """:meth:`_send`, once the serial line has at most :data:`links.MAX_QUEUED_LINE_S` of
        bytes ahead of it: a program that sends faster than the line carries would otherwise
        fill the kernel's buffer, seconds of a slow line, and a ``#stop!`` would wait behind all
        of it. A stop() meanwhile goes first, and supersedes a motion frame waiting here."""
        queued_s = links.queued_line_s(self._link)
        if queued_s is None or queued_s() <= links.MAX_QUEUED_LINE_S:
            self._send(command)  # (the usual case: no wait, so nothing can come between)
            return
        stops_seen = self._session.stops_asked
        await self._wait_for_line()
        self._send(command, stops_seen=stops_seen)

    async def _wait_for_line(self) -> None:
        """Wait until the serial line has at most :data:`links.MAX_QUEUED_LINE_S` of bytes
        ahead of the next frame."""
        queued_s = links.queued_line_s(self._link)
        while queued_s is not None and (ahead_s := queued_s() - links.MAX_QUEUED_LINE_S) > 0:
            await asyncio.sleep(ahead_s)
            queued_s = links.queued_line_s(self._link)  # (a reopened link's, from now on)

    def _send(
        self, command: Command, *, by_session: bool = False, stops_seen: int | None = None
    ) -> None:
        # (Written, or queued for the port, before it returns: a set command never waits here,
        # so a stop() after it follows it on the wire. Before it, a command method waits for a
        # slow serial line (_send_paced), as send() and a raw frame do but for a stop.)
        stop = command == operations.STOP
        if _running_loop() is not self._loop:
            if not stop:
                raise self._wrong_loop_error()
            self._stop_from_another_loop()
            return
        if stop:
            self._session.stop_asked()
            if self._link_down and not self._closed:
                self._stop_while_reconnecting()
                return
        if stop and self._closed and self._lost is None:
            # close() is letting the queries on the wire be answered: the port is still open,
            # and a stop still goes out until it is closed (as the blocking client's). Nothing
            # else due is written but an expired motion's zero thrust (P23).
            self._flush_due()
        else:
            self._check_open()
        try:
            self._write(
                self._session.command(
                    command, self._clock(), by_session=by_session, stops_seen=stops_seen
                )
            )
        except ConnectionLostError:
            if not (command == operations.STOP and self._link_down and not self._closed):
                raise
            # Cut off by the loss: the reopened link's first frame (see _on_lost).
        self._arm_timer()  # a motion command may now expire
        self._emit()

    def _stop_while_reconnecting(self) -> None:
        """``stop()`` while the link is being reopened. Not an error: late, a stop is still
        wanted (a link that never comes back leaves the controller's own link-loss failsafe to
        stop the robot, P17). On a reopened link being readied it goes out at once, not after
        the probe's answer (see :meth:`Session.stop_while_reconnecting`); with no link open, it
        is the next one's first frame."""
        data = self._session.stop_while_reconnecting(self._clock())
        if not data:
            logger.info(
                "#stop! asked for while %s is down: its first frame", self._link.description
            )
        else:
            try:
                self._transport.write(data)  # the reopened link's
            except ConnectionLostError as error:  # the attempt fails: kept for the next link
                self._on_lost(error)
        self._emit()

    def subscribe(self, callback: EventCallback) -> None:
        """Call ``callback`` with every event from now on, as ``on_event`` is (in the loop).

        Example::

            rov.subscribe(lambda event: print(event.direction, event))
        """
        self._subscribers.append(subscriber(callback))
        self._session.record_events()

    def _emit(self) -> None:
        """Hand the session's events to ``on_event`` and the subscribers, log its notices.

        Called from inside a callback (which made events: a ``stop()``, a ``close()`` started
        as an eager task), it leaves them to the delivery under way, which hands them on once
        the callback returns: in order, and no callback is called from inside itself (as the
        blocking client's).
        """
        session = self._session
        if not (session.events or session.notices) or self._delivering:
            return
        self._delivering = True
        try:
            while session.events or session.notices:
                events = session.take_events()
                notices = session.take_notices()
                deliver(events, notices, self._options.on_event, self._hook_failures)
                for subscriber in self._subscribers:
                    deliver(events, (), subscriber, self._hook_failures)
        finally:
            self._delivering = False

    def _flush_due(self) -> None:
        """Write what the session has due (a fence, a keep-alive, zero thrust); while closing,
        only zero thrust (P23)."""
        session = self._session
        take = session.take_outbox_when_closing if self._closed else session.take_outbox
        data = take(self._clock())
        if data and self._lost is None:
            with contextlib.suppress(ConnectionLostError):  # recorded: the waiters see it
                self._write(data)

    async def _request(self, command: Command) -> list[Response]:
        """Send a query until it is answered (retries); its replies."""
        return await self._ask(operations.Query(command, list))

    async def _ask(self, query: operations.Query[T]) -> T:
        """Send a query until it is answered (retries); its replies, read by ``query.read``.

        One coroutine for the whole query: every layer of coroutines costs a polling loop.
        """
        if _running_loop() is not self._loop:
            raise self._wrong_loop_error()
        if self._link_down:
            await self._await_link()
        command = query.command
        failures: list[str] = []
        slots = self._in_flight
        if slots.free:  # the usual case, without a coroutine
            slots.free -= 1
        else:
            self._check_open()  # (no wait for a slot on a link already gone)
            await slots.take()
        slot_handed_over = False
        try:
            for attempt in range(self._options.retries + 1):
                # A loop: the switch that ends may wake another switch before this query.
                while self._switching_mode:
                    self._check_open()  # (closed meanwhile: no wait for the switch to end)
                    await self._mode_settled.wait()
                # Every attempt, and after any wait for a slot or a mode switch: the link may
                # have been lost meanwhile, and a query queued on a lost link is never settled.
                if self._lost is not None or self._closed or self._link_down:
                    self._check_open()
                session = self._session
                now = self._clock()
                if attempt:  # (the general path: its event marks it a retry)
                    ready = session.query(command, now, retry=True)
                else:  # the usual case (nothing due or held) without the general path's work
                    ready = session.fast_query(command, now) or session.query(command, now)
                data, pending = ready
                waiter = pending.waiter = self._loop.create_future()
                if data:  # (nothing while queries are held back, P20)
                    try:
                        self._transport.write(data)
                    except ConnectionLostError as error:  # (as _write, without the call)
                        self._on_lost(error)
                        raise self._lost_error() from error
                # Time out at the latest at this query's deadline; a timer armed for earlier
                # already does (it re-arms when it fires). (Nothing is due now: the session's
                # query took it, to be written before the query.)
                if self._timer is None or self._timer_at > now + session.timeout_s:
                    self._arm_timer()  # (no timer whatever _timer_at says: never left unarmed)
                if session.events:
                    self._emit()
                try:
                    outcome: Outcome = await waiter
                except asyncio.CancelledError:
                    if not pending.settled:  # on the wire, or held back to be sent
                        self._hold_slot_until_settled(pending)
                        slot_handed_over = True
                    raise
                if outcome is _ANSWERED:
                    return query.read(pending.responses)
                if outcome is Outcome.DISCONNECTED:
                    raise self._lost_error()
                failures.append(outcome.value)
        finally:
            if slot_handed_over:
                pass
            elif slots.waiters:
                slots.release()
            else:  # (release's usual case, without the call)
                slots.free += 1
        raise QueryTimeoutError(command, failures, self._options.timeout_s, self._link.description)

    def _hold_slot_until_settled(self, pending: PendingQuery) -> None:
        """Keep the ``max_in_flight`` slot of a query whose caller was cancelled until the query
        settles (its reply, a timeout, the link lost): its frame is on the wire all the same,
        and the line must not carry more queries than ``max_in_flight``."""
        orphan: asyncio.Future[Outcome] = self._loop.create_future()
        orphan.add_done_callback(lambda _: self._in_flight.release())
        pending.waiter = orphan

    def _wake(self, settled: list[PendingQuery]) -> None:
        # A watcher (close, a checksum switch) is woken by whatever the session did, as the
        # session's own queries (a keep-alive, a fence) settle without being listed; it looks
        # at its queries again. (Nobody else waits on the event.)
        if self._settles_watched:
            self._settled.set()
        for query in settled:
            waiter = query.waiter
            if isinstance(waiter, _Future) and not waiter.done():
                waiter.set_result(query.outcome)

    def _on_data(self, data: bytes) -> None:
        if self._probe is not None:
            now = self._clock()
            self._probe.receive(data, now)
            self._session.count_outside(now, received=data)
            self._probe_data.set()
            return
        session = self._session
        now = self._clock()
        received = session.receive_reply(data, now)
        if isinstance(received, PendingQuery):  # the usual case: one whole reply, its query
            waiter = received.waiter  # (none for the session's own queries)
            if isinstance(waiter, _Future) and not waiter.done():
                waiter.set_result(_ANSWERED)
            if self._settles_watched:
                self._settled.set()
            return
        self._wake(received.settled)
        if session.has_outbox:
            self._flush_due()
            self._arm_timer()
        if received.unsolicited:
            self._drops.report(received.unsolicited, self._options.on_stray, now)
        if session.events or session.notices:
            self._emit()

    def _on_lost(self, error: ConnectionLostError) -> None:
        if self._lost is not None:
            return
        if self._reopen is not None and self._opened and not self._closed:
            if not self._link_ready.is_set():  # the reopened link, before it was ready
                self._attempt_lost = error
                self._probe_data.set()  # (the readiness wait gives up now)
                return
            self._link_ready.clear()  # (once per loss)
            self._link_down = True
            self._cancel_timer()
            self._wake(self._session.disconnect())  # their replies are gone
            # A stop or zero thrust that had not all gone goes first on the reopened link.
            self._session.write_failed(self._transport.undelivered)
            self._session.note_link("lost", f"{error}; reconnecting", self._clock())
            self._emit()
            self._reconnector = self._loop.create_task(self._reconnect())
            return
        self._lost = error
        self._cancel_timer()
        self._wake(self._session.disconnect())
        if self._opened and not self._closed:  # (while connecting: the connect's error says it)
            logger.warning("%s", error)

    async def _reconnect(self) -> None:
        """Reopen the port with backoff (0.1 s, doubling to 2 s) until it answers, or close()."""
        reopen = self._reopen
        assert reopen is not None
        description = self._link.description  # (the port's, whatever the attempts open)
        with contextlib.suppress(Exception):
            await self._transport.close()
        delays_s = reconnect_delays_s()
        failed = FailedAttempts(logger)
        attempts = 0
        while not self._closed:
            attempts += 1
            opening = self._loop.run_in_executor(None, reopen)
            try:
                # Shielded: when close() cancels this, the port being opened is closed once open.
                link = await asyncio.shield(opening)
            except (OSError, ValueError) as error:  # ConnectError is an OSError
                failed.note(attempts, error)
                await asyncio.sleep(next(delays_s))
                continue
            except asyncio.CancelledError:
                opening.add_done_callback(_close_opened)
                raise
            except Exception as error:  # a bug in reopen or a link scheme: no retry can help
                self._give_up_reconnecting(error, description)
                return
            self._link = link
            self._attempt_lost = None
            self._transport = transport_for(link, self._loop)
            self._transport.start(self._on_data, self._on_lost)
            session = self._session
            try:
                rest = session.link_reopened()  # (a stop() from now on is written at once)
                if rest:  # first, before any probe feeds the controller's watchdog (P17)
                    self._write(rest)
                    session.count_outside(self._clock(), sent=rest)
                await self._await_ready(reconnecting=True)
                session.reset_link()
                self._write(session.take_outbox(self._clock()))  # the mode, zero thrust
                # A link lost while it was being readied (reported, or found by that write) is
                # a failed attempt, not a connection: nothing else would ever notice it.
                if self._attempt_lost is not None:
                    raise self._attempt_lost
                session.link_ready()  # (not before: a failed attempt leaves them to the next)
            except (OSError, ValueError) as error:  # ConnectionLostError is an OSError
                failed.note(attempts, error)
                session.reopen_failed()
                with contextlib.suppress(Exception):
                    await self._transport.close()
                await asyncio.sleep(next(delays_s))
                continue
            except Exception as error:  # a bug in the link: as above
                session.reopen_failed()
                with contextlib.suppress(Exception):
                    await self._transport.close()
                self._give_up_reconnecting(error, description)
                return
            plural = "s" if attempts > 1 else ""
            session.note_link(
                "reconnected",
                f"{link.description} after {attempts} attempt{plural}",
                self._clock(),
            )
            self._link_ready.set()
            self._link_down = False
            self._arm_timer()
            self._emit()
            return

    def _give_up_reconnecting(self, error: Exception, description: str) -> None:
        """End reconnecting for good (see :func:`.reconnection.reconnecting_failed`)."""
        if self._closed:
            return
        lost = reconnecting_failed(description, error, logger)
        self._lost = lost
        self._link_down = False
        self._link_ready.set()  # (callers waiting for the link fail now, with that error)
        self._cancel_timer()
        self._wake(self._session.disconnect())
        self._emit()

    def _arm_timer(self) -> None:
        """Have :meth:`_on_timer` run at the session's next deadline (an earlier one re-arms)."""
        if self._lost is not None:
            return
        deadline = self._session.next_deadline()
        if self._timer is not None:
            if deadline is not None and self._timer_at <= deadline:
                return
            self._cancel_timer()
        if deadline is not None:
            self._timer = self._loop.call_at(deadline, self._on_timer)
            self._timer_at = deadline

    def _cancel_timer(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
            self._timer_at = math.inf

    def _on_timer(self) -> None:
        self._timer = None
        self._timer_at = math.inf
        if self._lost is not None:
            return
        session = self._session
        self._wake(session.tick(self._clock()))
        if session.has_outbox:
            self._flush_due()
        self._emit()
        self._arm_timer()


def _loop_clock(loop: asyncio.AbstractEventLoop) -> Callable[[], float]:
    """``loop.time``, or the clock it reads when it is asyncio's own (``time.monotonic``):
    read twice a query, and a Python method around a C function costs a call."""
    method = getattr(loop.time, "__func__", None)
    if method is asyncio.BaseEventLoop.time:
        return time.monotonic
    return loop.time


def _close_opened(opening: asyncio.Future[Link]) -> None:
    """Close a link whose reopening finished after the reconnection was given up."""
    if not opening.cancelled() and opening.exception() is None:
        opening.result().close()


class _Connecting(Coroutine[Any, Any, AsyncClient]):
    """What :func:`connect` returns: ``await`` it, or use it with ``async with``; a coroutine,
    so that ``asyncio.run(connect(url))`` and ``asyncio.create_task(connect(url))`` take it too
    (they take coroutines only, not any awaitable)."""

    def __init__(
        self, url: str, options: ClientOptions, baudrate: int | None, max_in_flight: int
    ) -> None:
        self._endpoint = parse_url(url, baudrate)
        self._options = options
        self._max_in_flight = max_in_flight
        self._client: AsyncClient | None = None
        self._opening: Coroutine[Any, Any, AsyncClient] | None = None  # once awaited or run

    def _coroutine(self) -> Coroutine[Any, Any, AsyncClient]:
        if self._opening is None:
            self._opening = self._open()
        return self._opening

    def send(self, value: Any) -> Any:
        return self._coroutine().send(value)

    def throw(self, *error: Any) -> Any:
        return self._coroutine().throw(*error)

    def close(self) -> None:
        if self._opening is not None:
            self._opening.close()

    async def _open(self) -> AsyncClient:
        # Opening a port or a TCP connection blocks: keep it off the loop. Shielded, as a
        # reconnection's: a cancelled connect closes the port once it is open (else the port,
        # or the simulator's thread, outlived the cancelled task).
        opening = asyncio.get_running_loop().run_in_executor(None, open_link, self._endpoint)
        try:
            link = await asyncio.shield(opening)
        except asyncio.CancelledError:
            opening.add_done_callback(_close_opened)
            raise
        try:
            endpoint = self._endpoint
            client = AsyncClient(
                link,
                self._options,
                max_in_flight=self._max_in_flight,
                reopen=lambda: open_link(endpoint),
            )
            return await client.open()
        except BaseException:
            link.close()
            raise

    def __await__(self) -> Generator[Any, None, AsyncClient]:
        return self._coroutine().__await__()

    # A program that forgets ``await`` or ``async with`` is told what to write, not that a
    # private class lacks an attribute or the context manager protocol. (Hidden from type
    # checkers, which report those mistakes themselves.)
    if not TYPE_CHECKING:

        def __getattr__(self, name: str) -> Any:
            raise AttributeError(
                f"rovlink.aio.connect() returns a connection still to be made, which has no "
                f"{name!r}: await it first (rov = await rovlink.aio.connect(url)), or use "
                "async with rovlink.aio.connect(url) as rov"
            )

        def __enter__(self) -> AsyncClient:
            raise TypeError(
                "rovlink.aio.connect() is for asyncio: use async with rovlink.aio.connect(url) as "
                "rov (in a coroutine), or with rovlink.connect(url) as rov for the blocking client"
            )

        def __exit__(self, *exc_info: object) -> None:
            """(Never reached: ``__enter__`` raises.)"""

    async def __aenter__(self) -> AsyncClient:
        self._client = await self._open()
        return self._client

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        assert self._client is not None
        await self._client.__aexit__(exc_type, exc, traceback)


def connect(
    url: str,
    *,
    timeout: float = 0.5,
    retries: int = 2,
    checksum: bool = False,
    algorithm: str = "crc8",
    keepalive: float | None = 1.0,
    boot_timeout: float | None = DEFAULT_BOOT_TIMEOUT_S,
    motion_timeout: float | None = DEFAULT_MOTION_TIMEOUT_S,
    baudrate: int | None = None,
    on_stray: StrayCallback | None = None,
    on_event: EventCallback | None = None,
    reconnect: bool = False,
    stop_on_close: bool = True,
    options: ClientOptions | None = None,
    max_in_flight: int = DEFAULT_MAX_IN_FLIGHT,
) -> _Connecting:
    """Connect to a controller for asyncio: ``async with connect(url) as rov`` or ``await``.

    The same URLs and options as :func:`rovlink.connect`; ``max_in_flight`` bounds the queries
    on the wire at once. ``on_stray`` is called in the event loop.

    Example::

        import asyncio, rovlink.aio

        async def main() -> None:
            async with rovlink.aio.connect("sim://") as rov:
                depths = await asyncio.gather(*(rov.depth_cm() for _ in range(10)))

        asyncio.run(main())
    """
    options = connect_options(
        options,
        timeout=timeout,
        retries=retries,
        checksum=checksum,
        algorithm=algorithm,
        keepalive=keepalive,
        on_stray=on_stray,
        boot_timeout=boot_timeout,
        motion_timeout=motion_timeout,
        on_event=on_event,
        reconnect=reconnect,
        stop_on_close=stop_on_close,
    )
    check_max_in_flight(max_in_flight)
    return _Connecting(url, options, baudrate, max_in_flight)
