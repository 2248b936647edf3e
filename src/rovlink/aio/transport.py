"""Byte transports for the asyncio client: the event loop reads the port, no thread in between.

:class:`FdTransport` watches a link's file descriptor (serial device, pseudo-terminal, TCP
socket) with ``loop.add_reader`` and reads whatever is waiting when it becomes readable; writes
go straight to the descriptor and only what does not fit is buffered until it is writable.

Ports without a descriptor (the in-process simulator, ``loop://``, ``rfc2217://``) have no
readiness to wait on, so :class:`ThreadTransport` reads them in one thread, hands each chunk to
the loop, and writes them in another; everything else — matching, timeouts, retries — still
runs in the loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Callable
from typing import Protocol

from rovlink.client import links, port_closing
from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import FdLink, Link
from rovlink.client.port_closing import PortClosing

# FdTransport and ThreadTransport are reached through transport_for, as a ByteTransport.
__all__ = ["ByteTransport", "transport_for"]

DataCallback = Callable[[bytes], None]
LostCallback = Callable[[ConnectionLostError], None]

_THREAD_READ_WAIT_S = 0.25
#: How long closing waits for what is still buffered to be written (a ``#stop!`` may be last):
#: the controller's own link-loss failsafe (P17) takes over after its watchdog, 2 s by default.
CLOSE_FLUSH_S = 2.0


class ByteTransport(Protocol):
    """Moves bytes between a link and the event loop.

    Example::

        transport = transport_for(link, asyncio.get_running_loop())
        transport.start(on_data=received.extend, on_lost=lost.append)
        transport.write(b"#qd!")
        await transport.close()
    """

    def start(self, on_data: DataCallback, on_lost: LostCallback) -> None:
        """Begin delivering received bytes (and the loss of the link) to the callbacks.

        Both callbacks run in the event loop's thread.

        Example::

            transport.start(on_data=decoder_input.extend, on_lost=lost.append)
        """
        ...

    def write(self, data: bytes) -> None:
        """Queue ``data`` for the port without blocking; raise ConnectionLostError if it is gone.

        Example::

            transport.write(b"#qd!")
        """
        ...

    def write_first(self, data: bytes) -> None:
        """Write ``data`` ahead of everything queued, without blocking: now as far as the port
        takes it, the rest first in the queue; raise ConnectionLostError if the link is gone.

        Example::

            transport.write_first(b"#stop!")
        """
        ...

    async def close(self) -> None:
        """Stop and release the link.

        Example::

            await transport.close()
        """
        ...

    @property
    def undelivered(self) -> bytes:
        """Bytes given to :meth:`write` that may not have reached the port when the link was
        lost (a whole frame even if part of it went): empty while everything went.

        Example::

            session.write_failed(transport.undelivered)
        """
        ...


class FdTransport:
    """A link with a file descriptor, driven by the loop's readiness callbacks."""

    def __init__(self, link: FdLink, loop: asyncio.AbstractEventLoop) -> None:
        self._link = link
        self._loop = loop
        self._fd = link.fileno()
        self._buffer = bytearray()
        # Every write not yet wholly written, from its first byte (the buffer is a tail of it).
        self._unconfirmed = bytearray()
        self._last_progress_at = 0.0  # when the buffer last shrank (or began)
        self._stall_timer: asyncio.TimerHandle | None = None
        self._on_data: DataCallback | None = None
        self._on_lost: LostCallback | None = None
        self._closed = False
        self._failed = False
        self._drained: asyncio.Future[None] | None = None  # set when closing waits for it

    def start(self, on_data: DataCallback, on_lost: LostCallback) -> None:
        """Watch the descriptor for input."""
        self._on_data = on_data
        self._on_lost = on_lost
        self._loop.add_reader(self._fd, self._readable)

    def _readable(self) -> None:
        try:
            data = self._link.recv_some()
        except ConnectionLostError as error:
            self._fail(error)
            return
        if data and self._on_data is not None:
            self._on_data(data)

    def write(self, data: bytes) -> None:
        """Write now what fits; buffer the rest until the descriptor is writable."""
        if self._closed:
            raise ConnectionLostError(f"{self._link.description}: closed")
        if self._buffer:
            self._buffer += data
            self._unconfirmed += data
            return
        try:
            written = self._link.send_some(data)
        except ConnectionLostError as error:
            self._unconfirmed += data
            self._fail(error)
            raise
        if written < len(data):
            self._buffer += data[written:]
            # (From the start of the frame cut off: the frames before it went whole.)
            self._unconfirmed += data[max(data.rfind(b"#", 0, written + 1), 0) :]
            self._loop.add_writer(self._fd, self._writable)
            # A line that takes nothing for the write timeout is lost, as the blocking
            # client's write says: else a #stop! would wait behind it for ever, and a reopened
            # link (reconnect=True) would never be tried.
            self._last_progress_at = self._loop.time()
            self._arm_stall_timer(links.WRITE_TIMEOUT_S)

    def write_first(self, data: bytes) -> None:
        """Write ``data`` now, ahead of what is buffered (a frame cut by it is resynchronised
        on ``#``, P1); what does not fit goes first in the buffer."""
        if self._closed:
            raise ConnectionLostError(f"{self._link.description}: closed")
        # (Where the frames not yet wholly written end: the buffer is their tail.)
        first_unwritten = len(self._unconfirmed) - len(self._buffer)
        try:
            written = self._link.send_some(data)
        except ConnectionLostError as error:
            self._unconfirmed[first_unwritten:first_unwritten] = data
            self._fail(error)
            raise
        if written == len(data):
            return
        self._unconfirmed[first_unwritten:first_unwritten] = data
        was_empty = not self._buffer
        self._buffer[:0] = data[written:]
        if was_empty:
            self._loop.add_writer(self._fd, self._writable)
            self._last_progress_at = self._loop.time()
            self._arm_stall_timer(links.WRITE_TIMEOUT_S)

    @property
    def undelivered(self) -> bytes:
        """Bytes given to :meth:`write` that may not have reached the port when the link was
        lost (a whole frame even if part of it went): empty while everything went.

        Example::

            session.write_failed(transport.undelivered)
        """
        return bytes(self._unconfirmed)

    def _arm_stall_timer(self, delay_s: float) -> None:
        self._stall_timer = self._loop.call_later(delay_s, self._check_stall)

    def _check_stall(self) -> None:
        self._stall_timer = None
        if not self._buffer or self._failed or self._closed:
            return
        timeout_s = links.WRITE_TIMEOUT_S
        stalled_s = self._loop.time() - self._last_progress_at
        if stalled_s < timeout_s:
            self._arm_stall_timer(timeout_s - stalled_s)
            return
        self._fail(
            ConnectionLostError(f"{self._link.description}: write blocked for {timeout_s:g} s")
        )

    def _writable(self) -> None:
        try:
            written = self._link.send_some(self._buffer)
        except ConnectionLostError as error:
            self._fail(error)
            return
        if written:
            self._last_progress_at = self._loop.time()
        del self._buffer[:written]
        if not self._buffer:
            self._unconfirmed.clear()
            self._loop.remove_writer(self._fd)
            self._settle_drained()
        elif written:
            # Only the frames not wholly written stay unconfirmed: on a line that never quite
            # drains, every frame written since it last did would pile up here.
            first_unwritten = len(self._unconfirmed) - len(self._buffer)
            frame_start = self._unconfirmed.rfind(b"#", 0, first_unwritten + 1)
            if frame_start > 0:
                del self._unconfirmed[:frame_start]

    def _settle_drained(self) -> None:
        if self._drained is not None and not self._drained.done():
            self._drained.set_result(None)

    def _fail(self, error: ConnectionLostError) -> None:
        self._failed = True
        self._settle_drained()
        if self._closed:
            return
        self._stop_watching()
        if self._on_lost is not None:
            self._on_lost(error)

    def _stop_watching(self) -> None:
        self._loop.remove_reader(self._fd)
        self._loop.remove_writer(self._fd)
        if self._stall_timer is not None:
            self._stall_timer.cancel()
            self._stall_timer = None

    async def close(self) -> None:
        """Write what is still buffered (for at most :data:`CLOSE_FLUSH_S`), stop watching and
        close the link: a client leaving by an error sends ``#stop!`` just before it closes,
        and a controller slow to read had it dropped with the buffer."""
        if self._closed:
            return
        self._loop.remove_reader(self._fd)  # (nobody reads replies any more)
        try:
            if self._buffer and not self._failed:
                self._drained = self._loop.create_future()
                # Not wait_for: on Python 3.10 it swallows a cancellation that comes as the
                # buffer drains (bpo-37658), and the caller's deadline would be lost.
                await asyncio.wait({self._drained}, timeout=CLOSE_FLUSH_S)
        finally:  # (cancelled too: the port is released)
            self._closed = True
            self._stop_watching()
            await close_link(self._link, self._loop)


class ThreadTransport:
    """A link without a descriptor: one thread reads, one writes, the loop does everything
    else.

    Such a port's write may wait (``spy://`` on a line with no room, up to its write timeout;
    ``rfc2217://`` on a stalled network, its socket's timeout): in the loop's thread it would
    hold up the whole program, a ``stop()`` and a bridge's heartbeats with it. The writing
    thread takes the bytes in order; a write that fails reports the link lost, as a read does.
    A port whose writes never wait (``writes_may_wait`` false: the in-process simulator) is
    written in the loop's thread, at once.
    """

    def __init__(self, link: Link, loop: asyncio.AbstractEventLoop) -> None:
        self._link = link
        self._loop = loop
        self._closing = False
        self._closed = False
        self._lost: ConnectionLostError | None = None  # (seen by either thread)
        self._on_lost: LostCallback | None = None
        # Bytes given to write() not yet written (the queue), and those being written.
        self._changed = threading.Condition()
        self._queue = bytearray()
        self._writing = b""
        self._failed_writes = bytearray()
        self._reader: threading.Thread | None = None
        self._writer: threading.Thread | None = None
        #: A port whose writes never wait (the simulator's) is written in the loop's thread.
        self._writes_at_once = not getattr(link, "writes_may_wait", True)

    def start(self, on_data: DataCallback, on_lost: LostCallback) -> None:
        """Start the reading and the writing thread."""
        self._on_lost = on_lost
        description = self._link.description
        self._reader = threading.Thread(
            target=self._read_loop,
            args=(on_data,),
            name=f"rovlink aio reader ({description})",
            daemon=True,
        )
        self._reader.start()
        if not self._writes_at_once:
            self._writer = threading.Thread(
                target=self._write_loop, name=f"rovlink aio writer ({description})", daemon=True
            )
            self._writer.start()

    def _read_loop(self, on_data: DataCallback) -> None:
        while not self._closing:
            try:
                data = self._link.read_available(_THREAD_READ_WAIT_S)
            except ConnectionLostError as error:
                self._lose(error)
                return
            if data:
                self._call_in_loop(on_data, data)

    def _write_loop(self) -> None:
        while True:
            with self._changed:
                while not self._queue and not self._closing and self._lost is None:
                    self._changed.wait()
                if not self._queue or self._lost is not None:
                    return  # (closing with everything written, or the link is gone)
                self._writing = bytes(self._queue)
                self._queue.clear()
            try:
                self._link.write(self._writing)
            except ConnectionLostError as error:
                self._lose(error)
                return
            with self._changed:
                self._writing = b""
                self._changed.notify_all()

    def _lose(self, error: ConnectionLostError) -> None:
        """The link is gone (either thread found it): report it once, unless closing."""
        with self._changed:
            if self._lost is not None:
                return
            self._lost = error
            self._changed.notify_all()
        links.abort_writes(
            self._link
        )  # (a write still waiting on the port: the writing thread ends)
        if not self._closing:
            self._call_in_loop(self._deliver_lost, error)

    def _deliver_lost(self, error: ConnectionLostError) -> None:
        # (In the loop, maybe after close() began: the client has a new link by then.)
        if not self._closed and self._on_lost is not None:
            self._on_lost(error)

    def _call_in_loop(
        self, callback: Callable[[object], None] | Callable[..., None], argument: object
    ) -> None:
        try:
            self._loop.call_soon_threadsafe(callback, argument)
        except RuntimeError:  # the loop is closed: nobody is listening any more
            self._closing = True

    def write(self, data: bytes) -> None:
        """Queue ``data`` for the writing thread; never waits for the port. (A port whose
        writes never wait, an in-process one, is written at once.)"""
        self._queue_for_writer(data, first=False)

    def write_first(self, data: bytes) -> None:
        """Queue ``data`` for the writing thread ahead of everything queued: it goes next,
        once a write already under way has ended; never waits for the port. (A port whose
        writes never wait is written at once.)"""
        self._queue_for_writer(data, first=True)

    def _queue_for_writer(self, data: bytes, *, first: bool) -> None:
        if self._writes_at_once:
            self._write_now(data)
            return
        with self._changed:
            if self._closing:
                raise ConnectionLostError(f"{self._link.description}: closed")
            if self._lost is not None:
                self._failed_writes += data
                raise ConnectionLostError(str(self._lost))  # (a new one: each has its traceback)
            if first:
                self._queue[:0] = data
            else:
                self._queue += data
            self._changed.notify_all()

    def _write_now(self, data: bytes) -> None:
        if self._closing:
            raise ConnectionLostError(f"{self._link.description}: closed")
        try:
            self._link.write(data)
        except ConnectionLostError:
            with self._changed:
                self._failed_writes += data
            raise

    @property
    def undelivered(self) -> bytes:
        """Bytes given to :meth:`write` that may not have reached the port when the link was
        lost: those the writing thread had not written, and those written after.

        Example::

            session.write_failed(transport.undelivered)
        """
        with self._changed:
            return self._writing + bytes(self._queue) + bytes(self._failed_writes)

    async def close(self) -> None:
        """Write what is still queued (for at most :data:`CLOSE_FLUSH_S`: a client leaving by
        an error sends ``#stop!`` just before it closes), stop the threads, close the link."""
        if self._closed:
            return
        self._closed = True
        try:
            if self._writer is not None:  # (else everything was written at once)
                await asyncio.to_thread(self._flush, CLOSE_FLUSH_S)
        finally:  # also when cancelled: a second close() returns at once
            with self._changed:
                self._closing = True
                self._changed.notify_all()
            links.abort_writes(self._link)  # (what the flush did not write in time is given up)
            self._link.wake()
            try:
                for thread in (self._reader, self._writer):
                    if thread is not None:
                        await asyncio.to_thread(thread.join, 2.0)
            finally:  # (cancelled while a thread ends: the port is released all the same)
                await close_link(self._link, self._loop)

    def _flush(self, timeout_s: float) -> None:
        with self._changed:
            self._changed.wait_for(
                lambda: self._lost is not None or not (self._queue or self._writing), timeout_s
            )


async def close_link(link: Link, loop: asyncio.AbstractEventLoop) -> None:
    """Close ``link`` in a thread of its own, waiting at most
    :data:`~rovlink.client.port_closing.CLOSE_TIMEOUT_S` without blocking the loop: a serial
    device's close waits in the kernel for its output to drain (or for good, on a USB adapter
    whose driver hangs), and ``rfc2217://``'s for its reader thread, then 0.3 s more. A close
    still under way then is reported and left to end in the background.

    Example::

        await close_link(link, asyncio.get_running_loop())
    """
    ended: asyncio.Future[None] = loop.create_future()

    def wake_the_loop() -> None:
        with contextlib.suppress(RuntimeError):  # (the loop is closed: nobody waits)
            loop.call_soon_threadsafe(_settle, ended)

    closing = PortClosing(link, then=wake_the_loop)
    timeout_s = port_closing.CLOSE_TIMEOUT_S
    try:
        await asyncio.wait({ended}, timeout=timeout_s)
    finally:
        ended.cancel()  # (cancelled: the close goes on in its thread)
    if not closing.ended():
        closing.report(timeout_s)


def _settle(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


def transport_for(link: Link, loop: asyncio.AbstractEventLoop) -> ByteTransport:
    """The native transport for ``link``: descriptor-driven when it has one.

    Example::

        link = open_link(parse_url("socket://localhost:5760"))
        transport = transport_for(link, asyncio.get_running_loop())
    """
    if isinstance(link, FdLink):
        return FdTransport(link, loop)
    return ThreadTransport(link, loop)
