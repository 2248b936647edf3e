"""A scripted fake controller for driver tests: answers queries on the far end of a file descriptor.

It decodes the host's frames exactly as a controller would (checksum mode follows ``#crcon!`` /
``#crcoff!``, bad checksums are dropped), records every byte and frame, and answers each query by
the next action of its script: ``reply`` (default), ``drop``, ``corrupt`` (a wrong checksum, or a
mangled frame with checksums off), ``debug`` (debug text around the reply), ``noise`` (line noise
before the reply), ``close`` (disconnect instead of answering), ``late`` (the controller
stalls for ``late_delay_s``: this reply and every reply due meanwhile go out when it ends, in
order, as a busy controller would send them), ``hold`` (the same stall, until the test calls
:meth:`FakeController.release`: a controller slow to answer for as long as a test needs).

It can also boot slowly (``boot_s``: input is ignored for that long after it starts, as an
Arduino-class board ignores it while it boots after the port opened), answer over a slow line
(``latency_s``: every reply goes out that long after its query, in order, as through a
serial-to-network bridge on a slow network) and :meth:`reset` (back to checksum mode off, as
after a power cycle, P21).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import select
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence

from rovlink.protocol import (
    BadFrame,
    Command,
    Decoder,
    Frame,
    Response,
    encode,
)

#: A chunk cut after each frame's ``!``, and what follows the last one.
_FRAMES_AND_REST = re.compile(rb"[^!]*!|[^!]+$")

DEFAULT_VALUES: dict[str, int] = {
    "qd": 123,
    "qr": 530,
    "q.l": 0,
    "qro": -1,
    "qpi": 15,
    "qhe": 275,
}


class FakeController:
    """Answers on ``fd`` from a thread; ``close()`` ends it and closes ``fd``."""

    def __init__(
        self,
        fd: int,
        *,
        algorithm: str = "crc8",
        values: dict[str, int] | None = None,
        on_close: Callable[[], None] | None = None,
        boot_s: float = 0.0,
        late_delay_s: float = 0.35,
        checksum: bool = False,
        script: Iterable[str] = (),
        latency_s: float = 0.0,
    ) -> None:
        self._fd = fd
        self.latency_s = latency_s
        #: The latencies of the next replies in turn, before ``latency_s`` again (a line whose
        #: delay varies; a reply never overtakes an earlier one only if they do not decrease).
        self.latencies_s: deque[float] = deque()
        self._booted_at = time.monotonic() + boot_s
        self.late_delay_s = late_delay_s
        #: Bytes that arrived while booting, and were lost.
        self.ignored = bytearray()
        self._on_close = on_close
        self.decoder = Decoder(algorithm=algorithm)
        self.decoder.checksum_enabled = checksum  # (on from the start: a controller running on)
        self.values = dict(DEFAULT_VALUES if values is None else values)
        #: The actions for the next queries (see :meth:`then`); ``script`` is there before the
        #: first byte is read.
        self.script: deque[str] = deque(script)
        self.raw = bytearray()
        self.commands: list[Command] = []
        self.bad_frames: list[BadFrame] = []
        self.queries_answered = 0
        #: Incremented for every query, so replies can carry a sequence number.
        self.query_count = 0
        #: When set, ``qd`` answers the query's sequence number (to check reply ordering).
        self.qd_counts_queries = False
        #: Called (on the fake's thread) whenever a query is dropped.
        self.on_drop: Callable[[], None] | None = None
        self.resets = 0
        self._stalled_until = 0.0
        self._held = bytearray()
        self._condition = threading.Condition()
        # Held from deciding what to write until it is written, by the reading thread and by
        # the end of a stall alike: replies leave in the order they were due, as a real
        # controller's do (else a reply due after a stall could overtake the held ones).
        self._write_order = threading.Lock()
        self._wake_r, self._wake_w = os.pipe()
        self._stopping = False
        self._reading = True
        self._thread = threading.Thread(target=self._run, name="fake controller", daemon=True)
        self._thread.start()

    @classmethod
    def on_socketpair(cls, **kwargs: object) -> tuple[FakeController, socket.socket]:
        """A fake on one end of a socket pair; the other end is returned for the client."""
        ours, theirs = socket.socketpair()
        fake = cls(ours.detach(), **kwargs)  # type: ignore[arg-type]
        return fake, theirs

    # -- scripting and inspection ----------------------------------------------------------

    def then(self, *actions: str) -> FakeController:
        """Queue actions for the next queries, in order."""
        with self._condition:
            self.script.extend(actions)
        return self

    def wait_for(
        self,
        predicate: Callable[[FakeController], bool],
        timeout_s: float = 5.0,
    ) -> bool:
        """Wait until ``predicate(self)`` holds (checked whenever a frame arrives)."""
        with self._condition:
            return self._condition.wait_for(lambda: predicate(self), timeout_s)

    def frames(self) -> list[str]:
        """The commands received, as frames without checksums (``#th.270.25!``)."""
        with self._condition:
            return [str(command) for command in self.commands]

    def send(self, data: bytes) -> None:
        """Write unsolicited bytes to the host."""
        os.write(self._fd, data)

    def reset(self) -> None:
        """Reset as after a power cycle: checksum mode off, input lost while it boots."""
        with self._condition:
            self.decoder.checksum_enabled = False
            self.decoder.reset()
            self.resets += 1

    def boot(self, boot_s: float) -> None:
        """Ignore input for ``boot_s`` from now (a reset followed by a boot)."""
        with self._condition:
            self._booted_at = time.monotonic() + boot_s

    def release(self) -> None:
        """End a stall begun by a ``hold`` action: the replies held go out, in order."""
        self._end_stall()

    def stop_reading(self) -> None:
        """Hang: read nothing more (the port stays open), so that the host's bytes pile up in
        the line until its writes find no room."""
        with self._condition:
            self._reading = False
        os.write(self._wake_w, b"x")

    def close(self) -> None:
        """Disconnect: the host sees the end of the stream."""
        with self._condition:
            if self._wake_w < 0:
                return
            self._stopping = True
        os.write(self._wake_w, b"x")
        if threading.current_thread() is not self._thread:
            self._thread.join(2.0)
        os.close(self._wake_r)
        os.close(self._wake_w)
        self._wake_w = -1

    # -- the controller ---------------------------------------------------------------------

    def _run(self) -> None:
        try:
            while not self._stopping:
                watched = [self._fd, self._wake_r] if self._reading else [self._wake_r]
                ready, _, _ = select.select(watched, [], [], 1.0)
                if self._wake_r in ready and not self._stopping:
                    os.read(self._wake_r, 64)
                if self._fd not in ready:
                    continue
                try:
                    data = os.read(self._fd, 4096)
                except OSError:
                    break
                if not data:
                    break
                self._receive(data)
        finally:
            # Under the write-order lock, and marked closed: a stall's timer that ends later
            # must not write into whatever descriptor reuses the number (the next test's).
            with self._write_order, contextlib.suppress(OSError):
                fd, self._fd = self._fd, -1
                os.close(fd)
            with self._condition:
                self._condition.notify_all()
            if self._on_close is not None:
                self._on_close()

    def _receive(self, data: bytes) -> None:
        # Frame by frame, as a controller takes them: a mode change (#crcon!) then applies from
        # the next frame however the host's bytes were chunked (P3).
        for piece in _FRAMES_AND_REST.findall(data):
            self._receive_piece(piece)

    def _receive_piece(self, data: bytes) -> None:
        with self._write_order:
            self._answer_piece(data)

    def _answer_piece(self, data: bytes) -> None:
        replies = bytearray()
        with self._condition:
            if time.monotonic() < self._booted_at:
                self.ignored += data
                self._condition.notify_all()
                return
            self.raw += data
            for event in self.decoder.feed(data):
                if isinstance(event, BadFrame):
                    self.bad_frames.append(event)
                    continue
                if not isinstance(event, Frame) or not isinstance(event.message, Command):
                    continue
                command = event.message
                self.commands.append(command)
                if command.spec.is_query:
                    action = self.script.popleft() if self.script else "reply"
                    if action == "close":
                        self._stopping = True
                        break
                    replies += self._answer(command, action)
            if replies and self._stalled_until:
                self._held += replies  # stalled: they go out, in order, when it ends
                replies = bytearray()
            self._condition.notify_all()
        latency_s = self.latencies_s.popleft() if replies and self.latencies_s else self.latency_s
        if replies and latency_s:
            timer = threading.Timer(latency_s, self._write_later, args=(bytes(replies),))
            timer.daemon = True
            timer.start()
        elif replies:
            with contextlib.suppress(OSError):  # the host may have gone already
                os.write(self._fd, bytes(replies))

    def _write_later(self, replies: bytes) -> None:
        with self._write_order:
            if self._fd >= 0:  # (closed meanwhile)
                with contextlib.suppress(OSError):
                    os.write(self._fd, replies)

    def _end_stall(self) -> None:
        with self._write_order:
            with self._condition:
                self._stalled_until = 0.0
                held, self._held = bytes(self._held), bytearray()
            if self._fd >= 0:  # (closed meanwhile)
                with contextlib.suppress(OSError):  # the host may have gone already
                    os.write(self._fd, held)

    def _reply_frames(self, command: Command) -> list[bytes]:
        self.query_count += 1
        checksum = self.decoder.algorithm if self.decoder.checksum_enabled else None
        frames = []
        for name in command.spec.replies:
            value = self.values[name]
            if name == "qd" and self.qd_counts_queries:
                value = self.query_count % 10000
            frames.append(encode(Response(name, (value,)), checksum))
        return frames

    def _answer(self, command: Command, action: str) -> bytes:
        frames = self._reply_frames(command)
        if action == "drop":
            if self.on_drop is not None:
                self.on_drop()
            return b""
        self.queries_answered += 1
        if action == "corrupt":
            first = frames[0]
            if self.decoder.checksum_enabled:  # flip a checksum digit
                digit = first[-2:-1]
                frames[0] = first[:-2] + (b"0" if digit != b"0" else b"1") + first[-1:]
            else:  # a letter where a digit belongs
                frames[0] = first[:-2] + b"x!"
        if action == "debug":
            return b"depth pid: p=12 i=1 d=4\r\n" + b"".join(frames) + b"\r\nmode depth\r\n"
        if action == "noise":
            return b"\x00~ noise ~\r\n" + b"".join(frames)
        if action == "hold":
            self._stalled_until = math.inf  # until release()
        if action == "late":
            self._stalled_until = time.monotonic() + self.late_delay_s
            timer = threading.Timer(self.late_delay_s, self._end_stall)
            timer.daemon = True
            timer.start()
        return b"".join(frames)


class FakeControllerServer:
    """A TCP port on 127.0.0.1 where a fake controller answers each connection, as a board does
    after every power-up (``fakes``, in the order of the connections).

    ``boot_s``: how long each controller ignores its input after the connection (a board
    booting), ``first_boot_s`` the first one's if it differs; ``script``: each controller's
    actions for its first queries (:meth:`FakeController.then`), in place before the
    connection's first byte; ``refuse``: nobody listens on the port (the adapter is still
    unplugged: a connection is refused, and one the kernel had completed but not handed over is
    reset); ``checksum_on_accept``: new connections find the controller in checksum mode
    (only the link dropped: the board ran on); ``ended[i]`` is set once the i-th controller's
    connection is closed.
    """

    def __init__(
        self,
        boot_s: float = 0.0,
        *,
        first_boot_s: float | None = None,
        script: Sequence[str] = (),
    ) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self._port = self._server.getsockname()[1]
        self.url = f"socket://127.0.0.1:{self._port}"
        self._closed = False
        self.boot_s = boot_s
        self.first_boot_s = boot_s if first_boot_s is None else first_boot_s
        self.script = tuple(script)
        self.fakes: list[FakeController] = []
        self.ended: list[threading.Event] = []
        self._refuse = False
        self.checksum_on_accept = False
        self._listen(self._server)

    @property
    def refuse(self) -> bool:
        return self._refuse

    @refuse.setter
    def refuse(self, refuse: bool) -> None:
        # No listener at all, rather than one that closes what it accepts: a connection made
        # while refusing but accepted after would otherwise be served (a test's "reopened
        # link" then began with frames written before it was meant to be plugged back).
        if refuse == self._refuse or self._closed:
            return
        self._refuse = refuse
        if refuse:
            # (shutdown first: it wakes the accept() under way, which closing would leave
            # holding the port)
            with contextlib.suppress(OSError):
                self._server.shutdown(socket.SHUT_RDWR)
            self._server.close()
        else:
            self._server = socket.create_server(("127.0.0.1", self._port))
            self._listen(self._server)

    def _listen(self, server: socket.socket) -> None:
        thread = threading.Thread(
            target=self._accept, args=(server,), name="fake controller server", daemon=True
        )
        thread.start()

    def _accept(self, server: socket.socket) -> None:
        while True:
            try:
                connection, _ = server.accept()
            except OSError:
                return
            ended = threading.Event()
            self.ended.append(ended)
            boot_s = self.boot_s if self.fakes else self.first_boot_s
            self.fakes.append(
                FakeController(
                    connection.detach(),
                    boot_s=boot_s,
                    on_close=ended.set,
                    checksum=self.checksum_on_accept,
                    script=self.script,
                )
            )

    def close(self) -> None:
        self._closed = True
        self._server.close()
        for fake in self.fakes:
            fake.close()
