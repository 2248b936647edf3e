"""The blocking client: ``rovlink.connect(url)`` and one method per command of the protocol.

Callers write under a lock, so the queue of pending queries in the
:class:`~rovlink.client.session.Session` has the wire's order and any number of threads may
share one client. One thread at a time holds the *reader role*: it reads whatever the port has,
feeds it to the session (which matches replies to pending queries) and wakes the callers whose
queries it settled. A caller waiting for a reply takes the role itself when it is free, so a
reply reaches its caller without a hop through another thread — that hop would cost as much as
the controller's own turnaround. A background thread holds the role only while no caller has
been active for a moment: it passes on the controller's debug text and stray frames, sends the
keep-alive queries of an idle link and notices a lost connection; it steps aside (woken through
the link) as soon as a caller arrives. Callbacks run after the role is given up, so they may
use the client.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import TypeVar

from rovlink.client import links, operations
from rovlink.client.command_methods import CommandMethods
from rovlink.client.counters import LinkCounters
from rovlink.client.errors import (
    ConnectError,
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
from rovlink.client.session import Outcome, PendingQuery, Received, Session
from rovlink.client.stop_at_exit import stop_at_exit, stop_within
from rovlink.client.unsolicited import DropLog, HookFailureLog, deliver
from rovlink.client.url import parse_url
from rovlink.logs import get_logger
from rovlink.protocol import Command, Event, Response, Setting
from rovlink.protocol.frames import checksum_mode_frame

__all__ = ["Client", "connect"]

_NEVER = float("inf")
logger = get_logger("rovlink.client")

T = TypeVar("T")

# Plain names for the members used per query: an enum member costs a descriptor call to look up.
_PENDING = Outcome.PENDING
_ANSWERED = Outcome.ANSWERED
_get_ident = threading.get_ident


def _owns(lock: threading.RLock) -> bool:
    """Whether this thread holds ``lock`` (the owner check ``threading.Condition`` uses)."""
    return bool(lock._is_owned())  # type: ignore[attr-defined]


#: The background reader looks around (deadlines, keep-alive, close) at least this often.
_MAX_READ_WAIT_S = 0.25
#: The background reader takes the role back once callers have been quiet this long: a program
#: querying in a loop keeps it, and debug text waits at most this long in the port's buffer.
_CALLER_GRACE_S = 0.005
#: How long a call waits for another thread to deliver its events to the hook (see _emit).
_DELIVERY_WAIT_S = 1.0


class Client(CommandMethods):
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
        reopen: Callable[[], Link] | None = None,
    ) -> None:
        """Drive the controller on ``link`` (already open; the client closes it).

        With ``options.reconnect``, ``reopen`` opens the same port again after the link is lost.

        Waits until the controller answers (``boot_timeout``, P21), then puts it in the checksum
        mode asked for, whatever an earlier session or a reset left behind.

        Example::

            client = Client(open_link(parse_url("socket://localhost:5760")))
        """
        self._options = options or ClientOptions()
        self._link = link
        self._clock = clock
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
        # What answered no query (text, stray and bad frames), in the order it was read, for
        # ``on_stray``: kept under the state lock and delivered with the events, by one thread
        # at a time, so that a slow callback in one thread is not overtaken by another's.
        self._strays: list[Event] = []
        self._subscribers: list[EventCallback] = []
        # Lock order: the wire lock, then the state lock. Re-entrant locks, as they know their
        # owner: a call that an exception ends gives back what its thread still holds (see
        # _recover_after_error).
        self._wire_lock = threading.RLock()  # one writer at a time: queue order = wire order
        # Writes on a reopened link being readied (P21) take this lock, not the wire lock: a
        # stop() on it must not queue behind a write still held up on the lost link. Lock
        # order: the wire lock, then this one, then the state lock.
        self._readied_lock = threading.RLock()
        # A stop() that found that lock held: its holder writes the #stop! before letting go.
        self._stop_handed_over = False
        self._state_lock = threading.RLock()  # the session and everything below
        self._changed = threading.Condition(self._state_lock)  # a query settled, role released
        # The background reader waits apart, so that callers' notifications do not wake it.
        self._background_wakeup = threading.Condition(self._state_lock)
        # Events are delivered by one thread at a time, in order (see _emit).
        self._delivered = threading.Condition(self._state_lock)
        self._deliverer: int | None = None
        self._events_taken = 0  # events and notices taken from the session to be delivered
        self._events_delivered = 0  # ... and handed to every callback
        self._lost: ConnectionLostError | None = None
        self._closing = False
        self._reopen = reopen if options.reconnect else None
        self._reconnecting = False  # the link was lost and is being opened again
        # The reopened link while it is being readied (P21): a stop() is written on it at once.
        self._readied_link: Link | None = None
        self._stop_reconnecting = threading.Event()
        self._reconnector: threading.Thread | None = None
        self._closer: threading.Thread | None = None  # the thread in the first close()
        self._in_forked_child = False  # (see _forked)
        self._released = threading.Event()  # set when that close() has released the port
        self._reader_ident: int | None = None  # the thread holding the reader role
        self._mode_switcher: int | None = None  # the thread draining queries to switch checksum
        # Callers with a query on the wire, by thread (a thread has one at a time).
        self._callers: dict[int, PendingQuery | None] = {}
        self._waiting_callers = 0  # callers waiting on ``_changed``
        self._last_caller_at = float("-inf")
        self._background = threading.Thread(
            target=self._background_loop,
            name=f"rovlink reader ({link.description})",
            daemon=True,
        )
        self._background_ident: int | None = None
        # Links over a descriptor write without blocking: queries then take a shorter path.
        self._send_now: Callable[[bytes], int] | None = getattr(link, "send_some", None)
        # An in-process port (``sim://``): its writes take the port's own lock, never the line.
        self._link_writes_never_wait = getattr(link, "writes_may_wait", True) is False
        self._queued_line_s = links.queued_line_s(link)
        # A caller waiting for its reply reads with this (the link's; a test interrupts it).
        self._read_reply: Callable[[float], bytes] = link.read_available
        try:
            self._await_ready()
            # The mode frame is the driver's own (a replay of a recording leaves it out).
            self._send(operations.checksum(options.checksum), by_session=True)
            if options.checksum and options.boot_timeout_s is not None:
                self._confirm_checksum_mode()
        except BaseException:
            self._link.close()
            raise
        # Started after the first frame, so that an idle link is measured from it.
        self._background.start()
        self._background_ident = self._background.ident
        stop_at_exit(self)  # (the robot it moved is stopped if the program ends with it open)

    # -- the connection -------------------------------------------------------------------------

    def __enter__(self) -> Client:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        # Leaving by an error: the robot is made safe before it is let go of, whatever it was
        # sent, by the #stop! of close() (bounded the same way: a hung far end never holds the
        # error up for a write timeout, and nothing raised there hides it).
        self._close(leaving_by_error=exc_type is not None)

    def close(self) -> None:
        """Release the port; pending and later calls raise ConnectionLostError.

        If the program moved the robot or unlocked its motors since its last ``stop()``, and the
        link is up, ``#stop!`` goes out first (waited for at most 0.5 s; ``stop_on_close=False``
        leaves the robot as it is). Queries already on the wire are answered next (for at most
        ``timeout``), so that their replies do not greet the next connection as if they
        answered its queries.

        Example::

            rov = rovlink.connect("sim://")
            rov.close()
        """
        self._close(leaving_by_error=False)

    def _close(self, *, leaving_by_error: bool) -> None:
        """close(); ``leaving_by_error``: the ``with`` block was left by an exception, which
        owes the robot a ``#stop!`` whatever it was sent (also while another thread closes)."""
        if self._in_forked_child:  # the port is the parent's: nothing to write or close
            return
        current = threading.current_thread()
        stop_at_exit(self, wanted=False)
        with self._changed:
            if self._closing:
                closer = self._closer
                stop_due = leaving_by_error and self._stop_due_on_close(leaving_by_error=True)
            else:
                closer = None
                self._closer = current
                self._closing = True
                self._stop_reconnecting.set()
                # A reopened link that takes nothing would hold the reconnecting thread, and
                # the port, past this close() (its write gives up after 2 s).
                links.abort_writes(self._readied_link)
                self._background_wakeup.notify()
                self._changed.notify_all()
                on_the_wire = self._session.on_the_wire  # (nothing new is written now)
                stop_due = self._stop_due_on_close(leaving_by_error=leaving_by_error)
        if closer is not None:
            if stop_due:  # (the port is open until the first close() has let the wire settle)
                self._stop_on_close()
            # Closed once the port is released, whoever closes it (P22: the program may open
            # it again) — unless this thread is one the first close() waits for.
            if current not in (closer, self._background, self._reconnector):
                self._released.wait()
            return
        # close() from a signal handler, in the thread whose call it interrupted: that call
        # holds what it holds until the handler returns (then it raises ConnectionLostError).
        # Its query, on the wire, has no other reader, and what it holds is not close()'s to
        # give back (the call would then release locks it no longer held).
        interrupted_call = self._in_a_call()
        # close() from an event callback: this thread is delivering events, and goes on with
        # those of the close (its #stop!) once the callback returns. It keeps that role: another
        # thread delivering them would call the callbacks while this one still runs.
        delivering = self._deliverer == _get_ident()
        try:
            try:
                if stop_due:
                    self._stop_on_close()
                for query in () if interrupted_call else on_the_wire:
                    self._wait(query, owned=False)  # answered, or timed out, before the close
            finally:  # (a Ctrl-C in that wait still releases the port: P22, a next open)
                if not interrupted_call:
                    # (nothing, unless that wait was interrupted)
                    self._recover_after_error(keep_delivering=delivering)
                self._connection_lost(ConnectionLostError(f"{self._link.description}: closed"))
                self._link.wake()
                # (Not from an interrupted call: they wait for what it holds. They end once
                # the handler returns, as the client is closed.)
                for thread in () if interrupted_call else (self._background, self._reconnector):
                    if thread is not None and thread is not current and thread.ident is not None:
                        thread.join(timeout=2.0)  # (the reconnecting thread may hold a new port)
                with self._changed:  # a caller may still be in a read: it stops at the wake-up
                    self._waiting_callers += 1
                    self._changed.wait_for(
                        lambda: self._reader_ident in (None, threading.get_ident()), timeout=2.0
                    )
                    self._waiting_callers -= 1
                self._close_link_once_written()
        finally:
            self._released.set()

    def _in_a_call(self) -> bool:
        """Whether this thread is inside a call of this client: it holds one of its locks, the
        reader role or a query (close() from a signal handler that interrupted that call)."""
        me = _get_ident()
        return (
            _owns(self._wire_lock)
            or _owns(self._readied_lock)
            or _owns(self._state_lock)
            or self._reader_ident == me
            or me in self._callers
        )

    def _forked(self, error: ConnectionLostError) -> None:
        """In a child made with ``os.fork()`` (its only thread, before it runs on): every call
        raises ``error``, and close() neither writes nor closes the port, the parent's."""
        self._in_forked_child = True
        self._lost = error
        self._reconnecting = False
        self._readied_link = None
        self._reader_ident = None
        self._deliverer = None
        # A lock that another of the parent's threads held at the fork is held for good here.
        self._wire_lock = threading.RLock()
        self._readied_lock = threading.RLock()
        self._state_lock = threading.RLock()
        self._changed = threading.Condition(self._state_lock)
        self._background_wakeup = threading.Condition(self._state_lock)
        self._delivered = threading.Condition(self._state_lock)

    def _stop_due_on_close(self, *, leaving_by_error: bool = False) -> bool:
        """Whether letting go of the robot owes it a ``#stop!`` (state lock held): the program
        left its ``with`` block by an error, or moved the robot or unlocked it since its last
        stop and did not opt out; and a link can carry it."""
        wanted = leaving_by_error or (
            self._options.stop_on_close and self._session.moved_since_stop
        )
        return wanted and self._lost is None and not self._reconnecting

    def _stop_on_close(self) -> None:
        """Send ``#stop!`` as close() begins, waiting for it at most 0.5 s
        (:func:`~rovlink.client.stop_at_exit.stop_within`): a line that takes nothing (or a port
        that cannot give up a write) never holds close() up, and closing the port ends that
        write. A thread that holds the wire lock or the state lock already (close() from a
        signal handler, in the thread whose call it interrupted) writes it itself, as
        ``stop()`` does: a thread of its own would wait for that lock until it gave up. So does
        a thread interrupted in a read of an in-process port (``sim://``), whose own lock it
        may hold there, if no other thread is writing."""
        if _owns(self._wire_lock) or _owns(self._state_lock):
            self._write_stop_on_close_here()
            return
        if (
            self._reader_ident == _get_ident()
            and self._link_writes_never_wait
            and self._wire_lock.acquire(blocking=False)
        ):
            try:
                self._write_stop_on_close_here()
            finally:
                self._wire_lock.release()
            return
        stop_within(self._write_stop_on_close, self._link.description)

    def _write_stop_on_close_here(self) -> None:
        try:
            self._write_stop_on_close()
        except Exception:  # (logged, not raised, as stop_within does)
            logger.exception("%s: writing #stop!", self._link.description)

    def _stop_at_exit(self) -> None:
        """The program ends with the client open: the ``#stop!`` of close(), if due, and not
        the rest (waiting for the replies on the wire would hold the exit up, as after Ctrl-C;
        the system releases the port)."""
        with self._state_lock:
            due = not self._closing and self._stop_due_on_close()
        if due:
            self._stop_on_close()

    def _write_stop_on_close(self) -> None:
        try:
            self._send(operations.STOP, by_session=True)
        except ConnectionError as error:  # (lost meanwhile: nothing to stop on)
            logger.debug("#stop! on close: %s", error)

    def _close_link_once_written(self) -> None:
        """Close the port once no thread is writing on it (at most 2 s more): a descriptor
        closed under a write in another thread (a stop() from it) could be reused by the next
        port opened, and written to. A write still waiting for room is given up first."""
        links.abort_writes(self._link)
        writing_done = self._wire_lock.acquire(timeout=links.WRITE_TIMEOUT_S)
        try:
            close_within(self._link)  # (a close that hangs is reported and left to end)
        finally:
            if writing_done:
                self._wire_lock.release()

    def __repr__(self) -> str:
        """What it is connected to and whether the link is up: ``print(rov)`` in a program.

        Example::

            print(rov)  # <rovlink.client.Client /dev/ttyUSB0 at 115200 baud: open>
        """
        if self._closing or self._in_forked_child:
            state = "closed"
        elif self._lost is not None:
            state = "lost"
        else:
            state = "reconnecting" if self._reconnecting else "open"
        return f"<rovlink.client.Client {self._link.description}: {state}>"

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

    def frame_for(self, command: Command) -> bytes:
        """The bytes this client writes for ``command`` now: checksummed in checksum mode,
        ``#stop!`` always bare (P3).

        Example::

            rov.frame_for(Command("qd"))  # b"#qd!", or b"#qd8C!" in checksum mode
        """
        with self._state_lock:
            return self._session.frame_for(command)

    @property
    def counters(self) -> LinkCounters:
        """A snapshot of the link's counters: frames, timeouts, retries, checksum errors, ….

        Example::

            print(rov.counters.timeouts, rov.counters.checksum_errors)
        """
        with self._state_lock:
            return self._session.counters.copy()

    # -- commands: see command_methods (generated) ------------------------------------------

    # -- any command ----------------------------------------------------------------------------

    def send(self, command: Command) -> tuple[Response, ...]:
        """Send any command of the table; a query returns its replies (retried like the others).

        Example::

            from rovlink.protocol import Command
            rov.send(Command("th", (90, 40)))
            (reply,) = rov.send(Command("qd"))
        """
        command = operations.any_command(command)
        setting = command.setting
        if setting is not None and setting[0] is Setting.CHECKSUM:
            self.set_checksum(setting[1])
            return ()
        if command.spec.is_query:
            return tuple(self._request(command))
        self._send(command)
        return ()

    def send_raw(self, frame: str | bytes) -> tuple[Response, ...]:
        """Send a frame exactly as given, once; if it is a query, wait for and return its replies.

        For experiments: the frame is not checked or given a checksum, and is not retried. One
        command frame at a time (ValueError for more: their motion and replies would go
        untracked); text or broken frames around it go as they are. On a slow serial line it
        waits for the line as a command method does, but for a query and a ``#stop!`` (which,
        as :meth:`stop`, supersedes a motion frame still waiting).

        Example::

            rov.send_raw("#qd!")       # → (Response(name='qd', values=(57,)),)
            rov.send_raw(b"#bogus!")   # the controller drops it (see its debug output)
        """
        data = operations.raw_frame(frame)
        mode = checksum_mode_frame(data)
        if mode is not None:  # a mode frame by exact match, as the controller takes it (P3)
            self.set_checksum(mode)
            return ()
        try:
            with self._state_lock:
                command = self._session.raw_command(data)  # (ValueError for more than one)
                stop = command == operations.STOP
                if stop:  # as stop(): it supersedes what waits already
                    self._session.stop_asked()
                stops_seen = self._session.stops_asked
            if not stop and (command is None or not command.spec.is_query):
                self._wait_for_line()  # as a command method's frame (a query waits for replies)
            pending = self._send_query(data, stops_seen=stops_seen)
            if pending is None:
                self._emit()  # (what was sent, as a command's is: no wait reports it later)
                return ()
            outcome = self._wait(pending)
        except BaseException:
            self._recover_after_error()
            raise
        if outcome is Outcome.ANSWERED:
            return tuple(pending.responses)
        if outcome is Outcome.DISCONNECTED:
            raise self._lost_error()
        raise QueryTimeoutError(
            pending.command, [outcome.value], self._options.timeout_s, self._link.description
        )

    # -- internals ------------------------------------------------------------------------------

    def _switch_checksum(self, command: Command) -> None:
        """Send ``#crcon!``/``#crcoff!`` once the queries on the wire are answered in the old
        mode."""
        try:
            self._switch_checksum_as(_get_ident(), command)
        except BaseException:
            self._recover_after_error()
            raise

    def _switch_checksum_as(self, me: int, command: Command) -> None:
        """:meth:`_switch_checksum` for thread ``me``, which holds the switch meanwhile."""
        with self._state_lock:
            while self._mode_switcher is not None:  # another thread is switching: after it
                self._wait_for_change(None)
            self._mode_switcher = me
        try:
            # Until nothing is on the wire: a query that times out meanwhile sends a fence (P20)
            # in the old mode, whose reply must come in that mode too. A line that answered
            # nothing in a round after the first is not waited for any longer.
            options = self._options
            give_up_at = time.monotonic() + options.timeout_s * (options.retries + 2)
            rounds = 0
            while True:
                self._check_open()  # (not under the state lock: a reconnection waits on it)
                with self._state_lock:
                    if self._closing:
                        raise self._lost_error()
                    if self._session.has_outbox:  # (a fence due): out in the old mode
                        self._flush_due()
                    on_the_wire = self._session.pending
                if not on_the_wire or time.monotonic() >= give_up_at:
                    break
                outcomes = [self._wait(query, owned=False) for query in on_the_wire]
                rounds += 1
                if rounds > 1 and _ANSWERED not in outcomes:
                    break
            self._send(command)
        finally:
            with self._state_lock:
                self._mode_switcher = None
                self._notify_callers()

    def _check_open(self) -> None:
        if self._reconnecting:
            self._await_link()
        if self._lost is not None:
            raise self._lost_error()

    def _await_link(self) -> None:
        """While a lost link is being reopened, wait for it, at most ``timeout``."""
        timeout_s = self._options.timeout_s
        deadline = time.monotonic() + timeout_s
        with self._state_lock:
            while self._reconnecting and not self._closing:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise ConnectionLostError(
                        f"connection lost: {self._link.description}: not reopened within "
                        f"{timeout_s:g} s (reconnecting)"
                    )
                self._wait_for_change(remaining)

    def _lost_error(self) -> ConnectionLostError:
        lost = self._lost
        reason = str(lost) if lost is not None else f"{self._link.description}: closed"
        if lost is None and self._reconnecting and not self._closing:
            reason = f"{self._link.description}: lost, reconnecting"
        error = ConnectionLostError(f"connection lost: {reason}")
        error.__cause__ = lost
        return error

    def _connection_lost(self, error: ConnectionLostError) -> None:
        with self._state_lock:
            self._lose(error)

    def _lose(self, error: ConnectionLostError) -> None:
        """Settle everything as disconnected (state lock held); reopen the link if asked to."""
        if self._lost is not None:
            return
        if not self._closing:
            # A write still waiting for room on the lost link is given up now, not at its
            # write timeout: it holds the wire lock, and every write (a stop()) waits behind.
            # (Not while closing: a last #stop! may still be on its way out.)
            links.abort_writes(self._link)
        if self._reopen is not None and not self._closing:
            self._session.disconnect()  # what was on the wire fails: its replies are gone
            self._changed.notify_all()
            self._background_wakeup.notify()
            if not self._reconnecting:
                self._reconnecting = True
                self._session.note_link("lost", f"{error}; reconnecting", self._clock())
                self._reconnector = threading.Thread(
                    target=self._reconnect_loop,
                    daemon=True,
                    name=f"rovlink reconnect ({self._link.description})",
                )
                self._reconnector.start()
            return
        self._lost = error
        self._session.disconnect()
        self._changed.notify_all()
        if not self._closing and self._background_ident is not None:
            # (As the asyncio client: a program that was idle, the keep-alive's link lost,
            # hears of it before its next call. While connecting, the connect's error says it.)
            logger.warning("%s", error)

    def _reconnect_loop(self) -> None:
        """Reopen the port with backoff (0.1 s, doubling to 2 s) until it answers, or close()."""
        with self._state_lock:  # whoever read the old link has let go of it
            self._waiting_callers += 1
            self._changed.wait_for(lambda: self._reader_ident is None, timeout=2.0)
            self._waiting_callers -= 1
        # Whoever wrote on it has let go too (a write waiting for room was given up: _lose).
        with self._wire_lock, contextlib.suppress(Exception):
            close_within(self._link)  # (a port whose close hangs is not waited for)
        reopen = self._reopen
        assert reopen is not None
        delays_s = reconnect_delays_s()
        failed = FailedAttempts(logger)
        attempts = 0
        while not self._stop_reconnecting.is_set():
            attempts += 1
            link: Link | None = None
            try:
                link = reopen()
                if self._stop_reconnecting.is_set():  # close() began while it was being opened
                    link.close()
                    return
                # Every write on it until it is ready holds the readied link's lock, so that a
                # stop() from another thread goes on it at once (see _stop_while_reconnecting).
                self._readied_lock.acquire()
                try:
                    with self._state_lock:
                        # (Under the lock close() takes to give up the readied link's writes:
                        # a close() that began since the check above did not see this link.)
                        if self._closing:
                            raise ConnectError(f"{link.description}: closed while reconnecting")
                        rest = self._session.link_reopened()
                        self._readied_link = link
                    if rest:  # first, before any probe feeds the controller's watchdog (P17)
                        link.write(rest)
                        with self._state_lock:
                            self._session.count_outside(self._clock(), sent=rest)
                except BaseException:  # (a stop handed over is kept for the next link)
                    self._readied_lock.release()
                    raise
                self._release_readied(link)
                self._await_ready(link)
                if not self._install(link, attempts):
                    return  # (closed meanwhile)
                break
            except (OSError, ValueError) as error:  # ConnectError, ConnectionLostError too
                failed.note(attempts, error)
                self._drop_attempt(link)
                self._stop_reconnecting.wait(next(delays_s))
            except Exception as error:  # a bug in reopen or a link scheme: no retry can help
                self._drop_attempt(link)
                self._give_up_reconnecting(error)
                break
        self._emit()

    def _drop_attempt(self, link: Link | None) -> None:
        """Close the link of a failed reconnection attempt, if it was opened."""
        if link is None:
            return
        with self._readied_lock:  # (no stop() is writing on it)
            with self._state_lock:
                self._session.reopen_failed()  # (a stop is kept for the next)
                self._readied_link = None
                self._stop_handed_over = False
            with contextlib.suppress(Exception):
                link.close()

    def _give_up_reconnecting(self, error: Exception) -> None:
        """End reconnecting for good (see :func:`.reconnection.reconnecting_failed`)."""
        with self._state_lock:
            if self._closing:
                return
        # (The port's description: the attempt's link is not kept. Logged outside the lock.)
        lost = reconnecting_failed(self._link.description, error, logger)
        with self._state_lock:
            if self._closing:
                return
            self._reconnecting = False
            self._lost = lost
            self._session.disconnect()
            self._changed.notify_all()
            self._background_wakeup.notify()

    def _release_readied(self, link: Link) -> None:
        """Let go of the readied link's lock (held once), first writing on ``link`` the
        ``#stop!`` a stop() handed over meanwhile (see :meth:`_stop_while_reconnecting`)."""
        lock = self._readied_lock
        try:
            self._write_then(link, b"", lock.release)
        except BaseException:  # (the attempt fails: the stop is kept for the next link)
            if _owns(lock):  # (a Ctrl-C may land after the release, on connect)
                lock.release()
            raise

    def _install(self, link: Link, attempts: int) -> bool:
        """Make the reopened ``link``, whose controller answered, the connection's: write the
        checksum mode and zero thrust (or a stop) first. False if close() began meanwhile."""
        with self._wire_lock:
            self._readied_lock.acquire()
            try:
                session = self._session
                with self._state_lock:
                    if self._closing:
                        self._readied_link = None
                        session.reopen_failed()
                        link.close()
                        return False
                    session.reset_link()
                    data = session.take_outbox(self._clock())  # the mode, zero thrust
                return self._write_then(link, data, lambda: self._settle_install(link, attempts))
            finally:
                self._readied_lock.release()

    def _write_then(self, link: Link, data: bytes, settle: Callable[[], T]) -> T:
        """Write ``data`` on the readied ``link``, then each ``#stop!`` a stop() hands over
        meanwhile (see :meth:`_stop_while_reconnecting`), and return ``settle()``, run under the
        state lock once none is left: a later stop() finds what it settled (the link's lock
        free, or the link installed), an earlier one handed its stop over first."""
        while True:
            if data:
                link.write(data)  # (not under the state lock: the link may be slow)
            with self._state_lock:
                if not self._stop_handed_over:
                    return settle()
                self._stop_handed_over = False
                data = self._session.stop_while_reconnecting(self._clock())

    def _settle_install(self, link: Link, attempts: int) -> bool:
        """The end of :meth:`_install` (state lock held): ``link`` becomes the connection's,
        unless close() began during its last write (False)."""
        session = self._session
        self._readied_link = None
        if self._closing:
            session.reopen_failed()
            link.close()
            return False
        session.link_ready()  # (not before: a failed write leaves them)
        self._link = link
        self._send_now = getattr(link, "send_some", None)
        self._queued_line_s = links.queued_line_s(link)
        self._read_reply = link.read_available
        self._reconnecting = False
        plural = "s" if attempts > 1 else ""
        session.note_link(
            "reconnected", f"{link.description} after {attempts} attempt{plural}", self._clock()
        )
        self._changed.notify_all()
        self._background_wakeup.notify()
        return True

    def _abandon(self, pending: PendingQuery) -> None:
        """Give up the query of a caller that was interrupted (state lock held): it may be
        on the wire, or its reply may have gone with the caller, so the session fences (P20)
        and no later query takes a reply meant for it."""
        if self._session.abandon(pending, self._clock()):
            self._notify_callers()  # (queries resynchronised with it: their callers retry)
        # The fence goes out with the next query, or from the background reader once no caller
        # is active: not from here, which may run under the wire lock that writing takes.
        self._background_wakeup.notify()

    def _recover_after_error(self, *, keep_delivering: bool = False) -> None:
        """Put back what this thread held when an exception ended its call (no lock needed on
        entry; none held on return); ``keep_delivering``: all but the delivery of events
        (close() from a callback, which delivers the rest once the callback returns).

        A Ctrl-C lands between any two bytecodes of the main thread: right after a lock was
        taken (the per-query path takes its locks by hand, which costs half a ``with`` block),
        while a lock is awaited, between taking the reader role and the code that gives it
        back. Rather than guard each of those steps, every call that takes them ends through
        here on an exception, and what its thread holds is known from outside: the locks
        (re-entrant, so they know their owner), the reader role, the mode switch, the delivery
        of events, and its query on the wire, abandoned (P20: the session fences, and no later
        query takes a reply meant for it). Otherwise the next call, ``stop()`` first, would wait
        for a lock forever.
        """
        me = _get_ident()
        lock = self._state_lock
        lock.acquire()  # (once more, if this thread still holds it)
        try:
            if self._reader_ident == me:
                self._reader_ident = None
                self._background_wakeup.notify()
            if self._mode_switcher == me:
                self._mode_switcher = None
            if self._deliverer == me and not keep_delivering:
                self._deliverer = None
                self._events_delivered = self._events_taken  # (what it held is gone)
                self._delivered.notify_all()
            if me in self._callers:
                pending = self._callers.pop(me)
                self._last_caller_at = self._clock()
                if pending is not None and pending.outcome is _PENDING:
                    self._abandon(pending)
            self._changed.notify_all()
        finally:
            while _owns(lock):
                lock.release()
            while _owns(self._readied_lock):
                self._readied_lock.release()
            while _owns(self._wire_lock):
                self._wire_lock.release()

    def _notify_callers(self) -> None:
        """Wake callers waiting for a settled query or the reader role (state lock held)."""
        if self._waiting_callers:
            self._changed.notify_all()

    def _wait_for_change(self, timeout_s: float | None) -> None:
        """Wait for a query to settle or the reader role to be free (state lock held)."""
        self._waiting_callers += 1
        try:
            self._changed.wait(timeout_s)
        finally:  # (a Ctrl-C in the wait)
            self._waiting_callers -= 1

    def _write(self, data: bytes) -> None:
        """Write under the wire lock; a failure is a lost connection."""
        try:
            self._link.write(data)
        except ConnectionLostError as error:
            self._connection_lost(error)
            raise self._lost_error() from error

    def _send(self, command: Command, *, by_session: bool = False) -> None:
        stop = command == operations.STOP
        with self._state_lock:
            if stop:  # (before it waits for anything: it supersedes what waits already)
                self._session.stop_asked()
            stops_seen = self._session.stops_asked
        if not stop:
            self._wait_for_line()
        while True:
            if stop and self._reconnecting and self._stop_while_reconnecting():
                return
            self._check_open()
            with self._wire_lock:
                with self._state_lock:
                    closing = self._closing and (not stop or self._reconnecting)
                    if self._lost is not None or closing:
                        raise self._lost_error()  # (lost, or closed, while this waited)
                    # Lost while this waited for the wire lock (behind a write that timed
                    # out): not written on the lost link, which would time out once more.
                    reconnecting = self._reconnecting
                    if not reconnecting:
                        motion_before = self._session.motion_as_sent()
                        # (SupersededByStopError if it moves or unlocks and a stop() was
                        # called while it waited: it would go out after the #stop!)
                        data = self._session.command(
                            command, self._clock(), stops_seen=stops_seen, by_session=by_session
                        )
                if not reconnecting:
                    try:
                        self._write(data)
                    except ConnectionLostError:
                        # A stop whose link is lost as it is written: the reopened link's
                        # first frame, as when it is asked for while the link is down.
                        if stop and self._reconnecting and self._stop_while_reconnecting():
                            break
                        with self._state_lock:  # (it may not have gone: a reopened link
                            self._session.write_interrupted(motion_before)  # zeroes it)
                        raise
                    except BaseException:  # (a Ctrl-C in a blocked write): it may not have gone
                        with self._state_lock:
                            self._session.write_interrupted(motion_before)
                        raise
                    break
        self._emit()

    def _wait_for_line(self) -> None:
        """Wait until the serial line has at most :data:`links.MAX_QUEUED_LINE_S` of bytes
        ahead of the next frame. A program that sends faster than the line carries (a loop of
        ``move``) would otherwise fill the kernel's buffer, seconds of a slow line, and a
        ``#stop!`` would wait behind all of it; a stop itself never waits here. (Not under a
        lock: a stop() meanwhile goes first, and supersedes a motion frame waiting here.)"""
        queued_s = self._queued_line_s
        if queued_s is None:
            return
        while (ahead_s := queued_s() - links.MAX_QUEUED_LINE_S) > 0:
            time.sleep(ahead_s)

    def _stop_while_reconnecting(self) -> bool:
        """``stop()`` while the link is being reopened; False if it no longer is (the usual path
        sends it). Not an error: late, a stop is still wanted (and a link that never comes back
        leaves the controller's own link-loss failsafe to stop the robot, P17). On a reopened
        link being readied it goes out at once, not after the probe's answer (see
        :meth:`Session.stop_while_reconnecting`); with no link open, it is the next one's first
        frame. It never waits for a write on the reopened link (a line that takes nothing holds
        one until it gives up): the writer writes the stop next."""
        lock = self._readied_lock  # (not the wire lock: a write on the lost link may hold it)
        held = lock.acquire(blocking=False)
        if not held:
            with self._state_lock:
                if not self._reconnecting or self._closing:
                    return False
                held = lock.acquire(blocking=False)  # (let go meanwhile)
                if not held:  # the writer looks for it before letting go (_release_readied)
                    self._stop_handed_over = True
                    self._session.hand_over_stop()
            if not held:
                self._emit()
                return True
        try:
            with self._state_lock:
                if not self._reconnecting or self._closing:  # (checked again under the lock)
                    return False
                data = self._session.stop_while_reconnecting(self._clock())
                link = self._readied_link
            if link is None:
                logger.info(
                    "#stop! asked for while %s is down: its first frame", self._link.description
                )
            else:
                try:
                    link.write(data)
                except ConnectionLostError as error:  # the attempt fails: kept for the next
                    logger.debug("#stop! on the reopened link: %s", error)
        finally:
            lock.release()
        self._emit()
        return True

    def _await_ready(self, link: Link | None = None) -> None:
        """P21: probe until the controller answers, then let the line go quiet (see readiness)."""
        boot_timeout_s = self._options.boot_timeout_s
        if boot_timeout_s is None:
            return
        link = link or self._link
        clock = time.monotonic  # a board boots in real time, whatever clock the session reads
        probe = ReadinessProbe(clock(), boot_timeout_s)
        while not probe.done(clock()):
            if self._stop_reconnecting.is_set():  # (close() during a reconnection)
                raise ConnectError(f"{link.description}: closed while reconnecting")
            now = clock()
            if probe.timed_out(now):
                raise probe.no_answer(link.description, network=isinstance(link, SocketLink))
            try:
                data = probe.bytes_to_send(now)
                if data:
                    self._readied_lock.acquire()  # (a stop() may write on a reopened link)
                    try:
                        link.write(data)
                    except BaseException:
                        self._readied_lock.release()
                        raise
                    self._release_readied(link)
                    with self._state_lock:
                        self._session.count_outside(now, sent=data)
                data = link.read_available(max(probe.wait_s(clock()), 0.001))
            except ConnectionLostError as error:
                raise probe.lost(error)  # noqa: B904 - it sets its own cause
            if data:
                received_at = clock()
                probe.receive(data, received_at)
                with self._state_lock:
                    self._session.count_outside(received_at, received=data)

    def _confirm_checksum_mode(self) -> None:
        with self._state_lock:
            self._session.reset_notices = False  # (the error below says what timeouts mean)
            self._session.own_queries = True
        try:
            self._request(Command("qd"))
        except QueryTimeoutError as error:
            raise checksum_mode_unconfirmed(
                self._link.description, self._options.algorithm, error
            ) from error
        finally:
            with self._state_lock:
                self._session.reset_notices = True
                self._session.own_queries = False

    def _flush_due(self) -> None:
        """Write what the session has due (state lock held on entry and on return)."""
        lock = self._state_lock
        lock.release()
        try:
            with self._wire_lock, lock:
                # While closing only zero thrust goes out (P23): no fence, no mode frame.
                session = self._session
                if self._reconnecting:  # no link to write on: the reopened one starts afresh
                    return
                take = session.take_outbox_when_closing if self._closing else session.take_outbox
                data = take(self._clock())
                if data and self._lost is None:
                    try:
                        written = self._send_now(data) if self._send_now else 0
                    except ConnectionLostError as error:
                        self._lose(error)
                        session.write_failed(data)
                        return
                    if written < len(data):
                        lock.release()
                        try:
                            self._write(data[written:])
                        except ConnectionLostError:
                            # Recorded as lost: the waiters see it. An expired motion's zero
                            # thrust in it may not have gone: a reopened link sends it first.
                            with lock:
                                session.write_failed(data)
                        finally:
                            lock.acquire()
        finally:
            lock.acquire()

    def subscribe(self, callback: EventCallback) -> None:
        """Call ``callback`` with every event from now on, as ``on_event`` is.

        Example::

            rov.subscribe(lambda event: print(event.direction, event))
        """
        callback = subscriber(callback)
        with self._state_lock:
            self._subscribers.append(callback)
            self._session.record_events()

    def _emit(self) -> None:
        """Hand the session's events to ``on_event`` and the subscribers, log its notices (no
        lock held).

        One thread delivers at a time, in the order the events happened, and goes on with what
        other threads add meanwhile: threads that each delivered their own overtook each other
        (a recording of the wire came out scrambled) and ran the hook at once. A thread whose
        events another is delivering waits until they are delivered (at most
        ``_DELIVERY_WAIT_S``), so that its call returns once the hook has seen them, unless it is
        that thread (a callback calling the client: its events follow when the callback
        returns).
        """
        session = self._session
        if session.events is None and not session.notices and not self._strays:
            return
        me = _get_ident()
        with self._state_lock:
            deliverer = self._deliverer
            if deliverer is not None:
                # The wait is a courtesy, never needed for order: not while this thread holds
                # the checksum switch (the deliverer's callback may query, which waits for the
                # switch) or closes (it may close too), and bounded whatever a callback does.
                if me not in (deliverer, self._mode_switcher) and not self._closing:
                    pending = len(session.events or ()) + len(session.notices) + len(self._strays)
                    target = self._events_taken + pending
                    give_up_at = time.monotonic() + _DELIVERY_WAIT_S
                    while self._deliverer is not None and self._events_delivered < target:
                        remaining_s = give_up_at - time.monotonic()
                        if remaining_s <= 0:
                            break
                        self._delivered.wait(remaining_s)
                return
            self._deliverer = me
        try:
            while True:
                with self._state_lock:
                    events = session.take_events()
                    notices = session.take_notices()
                    strays, self._strays = self._strays, []
                    if not (events or notices or strays):
                        self._deliverer = None
                        self._delivered.notify_all()
                        return
                    taken = len(events) + len(notices) + len(strays)
                    self._events_taken += taken
                    subscribers = tuple(self._subscribers)
                if strays:
                    self._drops.report(strays, self._options.on_stray, self._clock())
                deliver(events, notices, self._options.on_event, self._hook_failures)
                for subscriber in subscribers:
                    deliver(events, (), subscriber, self._hook_failures)
                with self._state_lock:
                    self._events_delivered += taken
                    self._delivered.notify_all()
        except BaseException:  # (a Ctrl-C in a callback): another thread may deliver now
            with self._state_lock:
                if self._deliverer == me:
                    self._deliverer = None
                    self._events_delivered = self._events_taken  # (what it held is gone)
                    self._delivered.notify_all()
            raise

    def _ask(self, query: operations.Query[T]) -> T:
        return query.read(self._request(query.command))

    def _request(self, command: Command) -> list[Response]:
        """Send a query until it is answered (retries); its replies, in the pending query's own
        list (no copy: nothing changes it once answered).

        The first attempt's usual case is spelled out here, as it is what a polling program
        does all day: a link that writes without blocking, nobody else reading the port, and
        the reply arriving whole in one read. Anything else goes on in :meth:`_wait` and
        :meth:`_attempts`. Whatever exception ends the call, :meth:`_recover_after_error`
        puts back what the thread held.
        """
        try:
            if self._send_now is None or self._reconnecting:
                return self._attempts(command)
            me = _get_ident()
            pending = self._send_query_holding_state(command, me)
            if pending is None:
                return self._attempts(command)
            if self._reader_ident is not None:  # another thread reads: it hands the reply over
                outcome = self._wait(pending, holding_state=True)
            else:
                lock = self._state_lock
                session = self._session
                self._reader_ident = me
                lock.release()
                try:
                    data = self._read_reply(session.timeout_s)  # (sent just now: all the timeout)
                except ConnectionLostError as error:
                    lock.acquire()
                    self._reader_ident = None
                    self._lose(error)
                    outcome = self._wait(pending, holding_state=True)
                else:
                    lock.acquire()
                    self._reader_ident = None
                    now = self._clock()
                    received = session.receive_reply(data, now) if data else None
                    if received is pending:  # the reply, whole, and no more
                        if self._waiting_callers:
                            self._changed.notify_all()
                        del self._callers[me]
                        self._last_caller_at = now
                        lock.release()
                        if session.notices:
                            self._emit()
                        return pending.responses
                    # Part of the reply, or more than it (text, noise, another caller's reply),
                    # or only an earlier caller's reply, or nothing.
                    if isinstance(received, Received) and received.unsolicited:
                        self._strays += received.unsolicited  # (delivered by _wait's _emit)
                    if session.has_outbox:
                        self._flush_due()
                    self._notify_callers()
                    outcome = self._wait(pending, holding_state=True)
            if outcome is _ANSWERED:
                return pending.responses
            return self._attempts(command, outcome)
        except BaseException:
            self._recover_after_error()
            raise

    def _attempts(self, command: Command, first: Outcome | None = None) -> list[Response]:
        """The attempts of a query (after the ``first``, if it was made and failed), each
        waited for by :meth:`_wait`; its replies, or QueryTimeoutError."""
        failures: list[str] = []
        retries = self._options.retries
        if first is not None:
            if first is Outcome.DISCONNECTED:
                raise self._lost_error()
            failures.append(first.value)
        me = _get_ident()
        for attempt in range(len(failures), retries + 1):
            if self._reconnecting:
                self._await_link()
            # (A retry takes the general path, which marks it one in its event.)
            fast = self._send_now is not None and not attempt
            pending = self._send_query_holding_state(command, me) if fast else None
            if pending is not None:
                outcome = self._wait(pending, holding_state=True)
            else:
                pending = self._send_query(command, retry=attempt > 0)
                assert pending is not None
                outcome = self._wait(pending)
            if outcome is _ANSWERED:
                return pending.responses
            if outcome is Outcome.DISCONNECTED:
                raise self._lost_error()
            failures.append(outcome.value)
        raise QueryTimeoutError(command, failures, self._options.timeout_s, self._link.description)

    def _send_query_holding_state(self, command: Command, me: int) -> PendingQuery | None:
        """Write and queue a query of thread ``me`` on a link that writes without blocking;
        return holding the state lock, or None (not holding it) while a checksum switch needs
        the general path. An exception leaves the locks to :meth:`_recover_after_error`.

        The frame is written first and queued after, both under the state lock (so that no
        reader can feed its reply to the session before it is queued): the bookkeeping then
        overlaps the controller's turnaround instead of delaying the frame.
        """
        send_now = self._send_now
        assert send_now is not None
        lock = self._state_lock
        lost: ConnectionLostError | None = None
        # (acquire and release spelled out: half the cost of a ``with`` block on 3.13)
        wire_lock = self._wire_lock
        wire_lock.acquire()
        lock.acquire()
        if self._lost is not None or self._closing:
            raise self._lost_error()
        if self._mode_switcher is not None or self._reconnecting:
            lock.release()
            wire_lock.release()
            return None
        ready = self._session.fast_query(command, self._clock())
        if ready is None:  # something due first, or queries held: the general path
            lock.release()
            wire_lock.release()
            return None
        data, pending = ready
        self._callers[me] = pending
        try:
            written = send_now(data)  # never blocks: the state lock is not held long
        except ConnectionLostError as error:
            self._lose(error)
            raise self._lost_error() from error
        background_reading = self._reader_ident == self._background_ident
        if written < len(data):  # the kernel's buffer is full: wait for room unlocked
            lock.release()
            try:
                self._write(data[written:])
            except ConnectionLostError as error:
                lost = error  # (waited for below, once the wire lock is let go)
            else:
                lock.acquire()
        wire_lock.release()
        if lost is not None:
            self._wait(pending)  # settled already: stops counting as active, reports
            raise lost
        if background_reading:
            self._link.wake()
        return pending

    def _send_query(
        self, query: Command | bytes, *, retry: bool = False, stops_seen: int | None = None
    ) -> PendingQuery | None:
        """Queue and write a query: a command (``retry``: again, after a failed attempt), or a
        raw frame (which may be no query at all; ``stops_seen``: the stops asked for when the
        program sent it, default now).

        The caller counts as active until :meth:`_wait` returns, so the background reader
        stays out of its way; if the background reader is reading, it is woken to step aside.
        An exception leaves the query to :meth:`_recover_after_error`.
        """
        session = self._session
        pending: PendingQuery | None
        lost: ConnectionLostError | None = None
        me = _get_ident()
        if stops_seen is None:  # (a raw frame that moves is superseded by a stop)
            stops_seen = session.stops_asked
        while True:
            with self._wire_lock:
                with self._state_lock:
                    if self._lost is not None or self._closing:
                        raise self._lost_error()
                    switcher = self._mode_switcher
                    reconnecting = self._reconnecting  # (lost while this waited for the lock)
                    ready = (switcher is None or switcher == me) and not reconnecting
                    if ready:
                        if isinstance(query, Command):
                            data, pending = session.query(query, self._clock(), retry=retry)
                        else:
                            data, pending = session.raw(query, self._clock(), stops_seen=stops_seen)
                        if pending is not None:
                            self._callers[me] = pending
                        background_reading = self._reader_ident == self._background_ident
                if ready:
                    try:
                        if data:  # (nothing while queries are held back, P20)
                            self._write(data)  # under the wire lock: queue order = wire order
                    except ConnectionLostError as error:
                        lost = error  # (waited for below, once the wire lock is let go)
                    break
            if reconnecting:  # wait for the reopened link (at most ``timeout``), then again
                self._check_open()
                continue
            # A checksum switch is draining the queue: wait for it outside the wire lock.
            with self._state_lock:
                while self._mode_switcher not in (None, me):
                    self._wait_for_change(None)
        if lost is not None:
            if pending is not None:
                self._wait(pending)  # settled already: stops counting as active, reports
            raise lost
        if background_reading:
            self._link.wake()
        return pending

    def _wait(
        self, pending: PendingQuery, *, owned: bool = True, holding_state: bool = False
    ) -> Outcome:
        """Wait until the attempt settles, reading the port whenever nobody else is.

        ``owned``: the caller queued ``pending`` (and stops counting as active here);
        ``holding_state``: the caller holds the state lock already (released here). An
        exception leaves the locks, the reader role and the query to
        :meth:`_recover_after_error`.
        """
        lock = self._state_lock
        session = self._session
        clock = self._clock
        me = _get_ident()
        if not holding_state:
            lock.acquire()
        now = clock()
        while pending.outcome is _PENDING:
            remaining = session.deadline(pending) - now
            if remaining == _NEVER:  # held back (P20): until the quiet line releases it
                remaining = (session.next_deadline() or now + _MAX_READ_WAIT_S) - now
            if remaining <= 0:
                session.tick(now)
                if session.has_outbox:
                    self._flush_due()
                self._notify_callers()
            elif self._reader_ident is not None:
                self._wait_for_change(remaining)
            else:
                self._reader_ident = me
                lock.release()
                try:
                    data = self._read_reply(remaining)
                    lost = None
                except ConnectionLostError as error:
                    data, lost = b"", error
                lock.acquire()
                self._reader_ident = None
                now = clock()
                if lost is not None:
                    self._lose(lost)
                elif data:
                    received = session.receive(data, now)
                    if received.unsolicited:
                        self._strays += received.unsolicited
                    if session.has_outbox:
                        self._flush_due()
                if self._waiting_callers:
                    self._changed.notify_all()
                continue  # ``now`` is fresh
            now = clock()
        if owned:
            del self._callers[me]
            self._last_caller_at = now
        lock.release()
        self._emit()
        return pending.outcome

    def _background_loop(self) -> None:
        lock = self._state_lock
        session = self._session
        while True:
            with lock:
                turn = self._next_turn()
            if turn is None:
                return
            if turn:
                try:
                    wait_s = self._housekeeping()
                    # What the housekeeping did is reported first, once the role is given up:
                    # a callback may query, and its reply is read by whoever holds the role.
                    if not (session.events or session.notices):
                        data = self._link.read_available(wait_s)
                        if data:
                            with lock:
                                received = session.receive(data, self._clock())
                                if received.unsolicited:
                                    self._strays += received.unsolicited
                                if session.has_outbox:
                                    self._flush_due()
                except ConnectionLostError as error:
                    if not self._closing:
                        self._connection_lost(error)
                finally:
                    with lock:
                        self._reader_ident = None
                        self._notify_callers()  # results, or the role, for a waiting caller
            self._emit()

    def _next_turn(self) -> bool | None:
        """Wait (state lock held) for the background reader's next turn: True once it holds the
        reader role, False when it did something due beside busy callers (to be reported), None
        once the client is closed or lost."""
        while True:
            if self._closing or self._lost is not None:
                return None
            if self._reconnecting:  # the reconnecting thread owns the link for now
                self._background_wakeup.wait(_MAX_READ_WAIT_S)
            elif self._reader_ident is None and not self._callers:
                quiet_s = self._clock() - self._last_caller_at
                if quiet_s >= _CALLER_GRACE_S:
                    self._reader_ident = threading.get_ident()
                    return True
                self._background_wakeup.wait(_CALLER_GRACE_S - quiet_s)
            else:
                wait_s = self._tick_beside_callers()
                if wait_s is None:
                    return False
                self._background_wakeup.wait(wait_s)

    def _tick_beside_callers(self) -> float | None:
        """While callers hold the reader role (state lock held), do what the session has due
        besides their replies: a thread polling without a pause must not keep an unrenewed
        motion going (P23), nor a long wait for a reply starve the keep-alive (P17). None if
        there is something to report, else how long to wait before looking again.

        An overdue query is left to its callers for a moment: they time it out themselves
        (a reply may be in the port's buffer while its reader is being scheduled).
        """
        session = self._session
        now = self._clock()
        due = session.next_deadline()
        if due is None:
            return _MAX_READ_WAIT_S
        if due > now:
            return min(due - now, _MAX_READ_WAIT_S)
        pending = session.pending
        if self._mode_switcher is not None and not pending:
            return _MAX_READ_WAIT_S  # (the switch sends its mode frame next: nothing before it)
        if pending and 0 <= now - session.deadline(pending[0]) < _CALLER_GRACE_S:
            return _CALLER_GRACE_S
        if session.tick(now):
            self._notify_callers()
        if session.has_outbox:
            self._flush_due()
        return None if session.events or session.notices else _CALLER_GRACE_S

    def _housekeeping(self) -> float:
        """Do what the session has due (timeouts, keep-alive, expired motion); how long the
        reader may block now."""
        now = self._clock()
        with self._state_lock:
            session = self._session
            if self._mode_switcher is None or session.pending:
                # (A checksum switch in progress talks anyway: no keep-alive in its way.)
                if session.tick(now):
                    self._notify_callers()
                if session.has_outbox:
                    self._flush_due()
            next_deadline = session.next_deadline()
        wait_s = _MAX_READ_WAIT_S
        if next_deadline is not None:
            wait_s = min(wait_s, next_deadline - now)
        return max(wait_s, 0.001)


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
) -> Client:
    """Connect to a controller and return a blocking :class:`Client` (a context manager).

    ``url``: a serial device or pseudo-terminal path, any pyserial URL (``socket://host:port``,
    ``loop://``, ``rfc2217://…``) with ``?baudrate=`` or ``baudrate`` (default 115200), or
    ``sim://`` for a simulated controller in this process (``sim://?leak_at=5&seed=1``).
    ``timeout`` (s) per query attempt; ``retries`` more attempts of a query after a timeout or a
    corrupt reply; ``checksum`` and ``algorithm`` (``crc8``, ``xor``, ``sum8``) the mode to put
    the controller in; ``keepalive`` (s) of idle link before a keep-alive query (``None``: never);
    ``boot_timeout`` (s) to wait for the controller to answer after the port opens (a board that
    resets on open boots for up to 2 s; ``None``: do not wait); ``motion_timeout`` (s) after which
    a motion command the program did not renew is expired with zero thrust (``None``: never);
    ``on_stray`` is called with debug text and frames nobody asked for, one call at a time and in
    the order they came, in whichever thread read them (one of the program's threads waiting for
    a reply, or the client's background reader), and ``on_event`` with every event of the
    connection (:mod:`rovlink.client.events`);
    ``reconnect=True`` reopens a lost port (an adapter unplugged and plugged back) with backoff,
    waits for the controller again and restores the checksum mode: the calls on the wire when it
    was lost raise ConnectionLostError, later calls wait for it up to ``timeout``;
    ``stop_on_close=False`` keeps ``close()`` from sending ``#stop!`` when the program moved the
    robot (a tool that hands the robot on, moving, to another program).
    ``options`` gives all of these at once as a :class:`ClientOptions` instead (its fields
    name the seconds: ``timeout_s``...; a keyword beside it is a TypeError).

    Example::

        import rovlink

        with rovlink.connect("/dev/ttyUSB0", checksum=True) as rov:
            rov.start()
            rov.move(0, 50)
            print(rov.sensors())
            rov.stop()
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
    endpoint = parse_url(url, baudrate)
    link = open_link(endpoint)
    try:
        return Client(link, options, reopen=lambda: open_link(endpoint))
    except BaseException:
        link.close()
        raise
