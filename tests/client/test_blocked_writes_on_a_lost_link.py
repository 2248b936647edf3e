"""Writes that a lost link cuts off (reconnect=True): ``stop()`` never queues behind a write that
cannot finish, and a stop or zero thrust that did not get out goes first on the reopened link."""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import socket
import threading
import time
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest

import rovlink
import rovlink.aio
from rovlink.client import Client, links
from rovlink.client.errors import ConnectionLostError, SupersededByStopError
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.links import Link, SocketLink
from rovlink.client.url import parse_url
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    ThreadCall,
    WatchedLock,
    client_options,
    fill_line,
    wait_until,
)
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = pytest.mark.integration

#: How soon a #stop! asked for must be on the wire when nothing but the client is in its way
#: (the write timeout, 2 s, is what the client waited for before).
PROMPT_S = 0.5


def _lost(events: list[ClientEvent]) -> bool:
    return any(isinstance(event, LinkState) and event.state == "lost" for event in events)


def _stopped(fake: FakeController) -> bool:
    return "#stop!" in fake.frames()


def _probed(fake: FakeController) -> bool:
    return "#qd!" in fake.frames()


class _StuckLines:
    """Reopened links whose far end, plugged back, reads nothing: their writes wait for room."""

    def __init__(self) -> None:
        self.far_ends: list[socket.socket] = []

    def open(self) -> Link:
        far_end, ours = socket.socketpair()
        self.far_ends.append(far_end)
        link = SocketLink(ours, "socket pair, reopened, stuck")
        fill_line(link)
        return link

    def first_was_let_go(self) -> bool:
        """Whether the first line's port was closed: its far end reads the end, past the fill."""
        far_end = self.far_ends[0]
        far_end.setblocking(False)
        with contextlib.suppress(BlockingIOError):  # (what the fill left)
            while far_end.recv(1 << 20):
                pass
        return far_end.recv(1) == b""


@pytest.fixture
def stuck() -> Iterator[_StuckLines]:
    """Lines that take nothing, for ``reopen`` (their far ends closed after the test)."""
    lines = _StuckLines()
    yield lines
    for far_end in lines.far_ends:
        far_end.close()


@pytest.mark.realtime
def test_a_stop_on_the_reopened_link_does_not_wait_for_a_write_blocked_on_the_lost_one(
    reopened: list[FakeController],
) -> None:
    # Before, the write waiting for room on the lost link held the wire lock until its 2 s
    # write timeout: the reopened link was not even probed meanwhile, and stop() waited too.
    far_end, host_end = socket.socketpair()  # a far end that stops reading: nobody reads it

    def reopen() -> Link:
        fake, ours = FakeController.on_socketpair(script=("hold",))  # slow to answer the probe
        reopened.append(fake)
        return SocketLink(ours, "socket pair, reopened")

    events: list[ClientEvent] = []
    options = client_options(reconnect=True, boot_timeout_s=2.0, on_event=events.append)
    link = SocketLink(host_end, "socket pair")
    far_end.send(b"$qd.0!")  # the answer to the first readiness probe
    rov = Client(link, options, reopen=reopen)
    try:
        fill_line(link)
        sent = rov.counters.frames_sent
        writer = ThreadCall(lambda: rov.move(90, 40))
        assert wait_until(lambda: rov.counters.frames_sent > sent)  # the #th is being written
        far_end.shutdown(socket.SHUT_WR)  # the link is lost: the reader sees its end
        assert wait_until(lambda: _lost(events))
        assert wait_until(lambda: bool(reopened))
        probed = reopened[0].wait_for(_probed, PROMPT_S)
        assert probed, "the reopened link was not probed while a write was blocked on the lost one"
        started = time.monotonic()
        rov.stop()
        returned_s = time.monotonic() - started
        assert reopened[0].wait_for(_stopped, CONDITION_TIMEOUT_S)
        stopped_s = time.monotonic() - started
        assert returned_s < PROMPT_S, f"stop() took {returned_s:.2f} s"
        assert stopped_s < PROMPT_S, f"#stop! on the reopened link after {stopped_s:.2f} s"
        # The blocked write was abandoned with its link, not left to time out.
        assert writer.done.wait(PROMPT_S)
        assert isinstance(writer.error, ConnectionLostError)
    finally:
        for fake in reopened:
            fake.release()
        rov.close()
        far_end.close()


class _SerialDevice:
    """A fake controller behind a pseudo-terminal, under a device name (as udev names an
    adapter: a symbolic link to whichever node it got)."""

    def __init__(self, name: Path) -> None:
        master, self._terminal = os.openpty()
        tty.setraw(self._terminal)  # no echo, no line editing, before the client opens it
        # (The terminal side stays open here too: a master side read with no terminal side
        # open fails, and the fake would hang up before the client opened it.)
        self.fake = FakeController(master)
        name.symlink_to(os.ttyname(self._terminal))

    def fill_line(self) -> None:
        """Fill the line towards a controller that stopped reading: the client's next write
        finds no room. (The terminal moves bytes on towards its master side a little later,
        so it is filled until it stays full.)"""
        os.set_blocking(self._terminal, False)
        while True:
            for chunk in (b"\r\n" * 1024, b" " * 16, b" "):
                with contextlib.suppress(BlockingIOError):
                    while os.write(self._terminal, chunk):
                        pass
            _, writable, _ = select.select([], [self._terminal], [], 0.05)
            try:
                os.write(self._terminal, b" ")
            except BlockingIOError:
                if not writable:
                    return

    def close(self) -> None:
        """Pull it out: the client's descriptor reads as hung up from now on (idempotent)."""
        self.fake.close()
        if self._terminal >= 0:
            os.close(self._terminal)
            self._terminal = -1


@pytest.fixture
def device_name(tmp_path: Path) -> Path:
    return tmp_path / "ttyROV"


@pytest.mark.realtime
def test_a_stop_behind_a_write_that_times_out_is_the_reopened_links_first_frame(
    device_name: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, the stop() waiting behind a write to a controller that stopped reading was
    # written on the link that write had just found dead: it waited the write timeout once
    # more, raised ConnectionLostError, and was lost (the reopened link got no #stop!, nor
    # zero thrust, as the motion was taken to be stopped).
    write_timeout_s = 0.5
    monkeypatch.setattr(links, "WRITE_TIMEOUT_S", write_timeout_s)
    first = _SerialDevice(device_name)
    second: _SerialDevice | None = None
    events: list[ClientEvent] = []
    rov = rovlink.connect(
        str(device_name),
        reconnect=True,
        keepalive=None,
        timeout=2.0,
        boot_timeout=2.0,
        motion_timeout=None,
        on_event=events.append,
    )
    try:
        rov.start()
        rov.move(90, 50)
        first.fake.stop_reading()  # the controller hangs
        first.fill_line()
        sent = rov.counters.frames_sent
        writer = ThreadCall(
            lambda: rov.move(90, 40)
        )  # waits for room, then times out: the link is lost
        assert wait_until(lambda: rov.counters.frames_sent > sent)
        device_name.unlink()  # plugged out and in again: a working controller, the same name
        second = _SerialDevice(device_name)
        started = time.monotonic()
        rov.stop()
        took_s = time.monotonic() - started
        assert took_s < write_timeout_s + PROMPT_S, f"stop() took {took_s:.2f} s"
        assert writer.done.wait(CONDITION_TIMEOUT_S)
        assert isinstance(writer.error, ConnectionLostError)
        assert second.fake.wait_for(_stopped, CONDITION_TIMEOUT_S)
        assert second.fake.frames()[0] == "#stop!"  # first, before the readiness probe
        assert rov.depth_cm() == 123
    finally:
        rov.close()
        first.close()
        if second is not None:
            second.close()


@pytest.mark.parametrize("how", ["the program's zero thrust", "an expired motion's zero thrust"])
def test_zero_thrust_cut_off_by_the_loss_of_the_link_goes_first_on_the_reopened_one(
    device_name: Path, monkeypatch: pytest.MonkeyPatch, how: str
) -> None:
    # Before, a zero thrust whose write the loss of the link cut off was taken as sent: the
    # reopened link began with the readiness probe, whose queries fed the watchdog (P17) of a
    # controller driving on at 50 % (a link that only dropped: no reset).
    write_timeout_s = 0.3
    monkeypatch.setattr(links, "WRITE_TIMEOUT_S", write_timeout_s)
    first = _SerialDevice(device_name)
    second: _SerialDevice | None = None
    expiring = how == "an expired motion's zero thrust"
    rov = rovlink.connect(
        str(device_name),
        reconnect=True,
        keepalive=None,
        timeout=2.0,
        boot_timeout=2.0,
        motion_timeout=0.5 if expiring else None,
    )
    try:
        rov.start()
        rov.move(90, 50)
        first.fake.stop_reading()  # the controller hangs
        first.fill_line()
        sent = rov.counters.frames_sent
        if not expiring:
            ThreadCall(lambda: rov.move(90, 0))  # waits for room, then times out: the link is lost
        assert wait_until(lambda: rov.counters.frames_sent > sent)  # the zero is being written
        device_name.unlink()  # plugged out and in again: the same name
        second = _SerialDevice(device_name)
        assert second.fake.wait_for(lambda fake: len(fake.frames()) >= 3, CONDITION_TIMEOUT_S)
        assert second.fake.frames()[:3] == ["#th.90.0!", "#crcoff!", "#qd!"]
    finally:
        rov.close()
        first.close()
        if second is not None:
            second.close()


def _port_url(device_name: Path, port: str) -> str:
    """The URL of the device: its name, or through pyserial's logging wrapper (``spy://``,
    read and written by pyserial rather than through the descriptor)."""
    if port == "spy":
        return f"spy://{device_name}?file={device_name.parent / 'spy.txt'}"
    return str(device_name)


@pytest.mark.parametrize("port", ["serial", "spy"])
@pytest.mark.parametrize("what", ["#stop!", "#th.90.0!"])
@pytest.mark.realtime
async def test_the_asyncio_client_gives_up_a_line_that_takes_nothing_and_starts_the_next_with_it(
    device_name: Path, monkeypatch: pytest.MonkeyPatch, what: str, port: str
) -> None:
    # Before, the asyncio client kept what a controller that stopped reading did not take in
    # its buffer for ever: the #stop! (or zero thrust) behind it never went out, and the link
    # was never taken for lost, so the adapter plugged back under the same name was never
    # opened.
    monkeypatch.setattr(links, "WRITE_TIMEOUT_S", 0.3)
    first = _SerialDevice(device_name)
    second: _SerialDevice | None = None
    try:
        async with rovlink.aio.connect(
            _port_url(device_name, port),
            reconnect=True,
            keepalive=None,
            timeout=2.0,
            boot_timeout=2.0,
            motion_timeout=None,
        ) as rov:
            await rov.start()
            await rov.move(90, 50)
            first.fake.stop_reading()  # the controller hangs
            first.fill_line()
            # Returns at once: the line takes it when it can (and the loop never waits for
            # it: through spy://, pyserial's write waited in the loop's thread).
            loop = asyncio.get_running_loop()
            started_s = loop.time()
            await (rov.stop() if what == "#stop!" else rov.move(90, 0))
            await asyncio.sleep(0)
            took_s = loop.time() - started_s
            assert took_s < 0.3 / 2, f"the event loop waited {took_s:.2f} s for the write"
            device_name.unlink()  # plugged out and in again: the same name
            second = _SerialDevice(device_name)
            got = await asyncio.to_thread(second.fake.wait_for, _probed, CONDITION_TIMEOUT_S)
            assert got, f"the reopened link was not probed: {second.fake.frames()}"
            assert second.fake.frames()[:3] == [what, "#crcoff!", "#qd!"]  # before the probe
            assert await rov.depth_cm() == 123
    finally:
        first.close()
        if second is not None:
            second.close()


@pytest.mark.parametrize("port", ["serial", "spy"])
async def test_an_asyncio_stop_written_as_the_adapter_is_pulled_out_goes_first_on_the_next(
    device_name: Path, port: str
) -> None:
    # Before, the stop() whose own write found the device gone raised ConnectionLostError and
    # was lost: the reopened link got zero thrust, and the motors stayed unlocked.
    first = _SerialDevice(device_name)
    second: _SerialDevice | None = None
    try:
        async with rovlink.aio.connect(
            _port_url(device_name, port),
            reconnect=True,
            keepalive=None,
            timeout=2.0,
            boot_timeout=2.0,
        ) as rov:
            await rov.start()
            await rov.move(90, 50)
            device_name.unlink()
            first.close()  # pulled out: the loop has not seen it yet, the stop's write does
            await rov.stop()
            second = _SerialDevice(device_name)  # plugged back under the same name
            got = await asyncio.to_thread(second.fake.wait_for, _probed, CONDITION_TIMEOUT_S)
            assert got, f"the reopened link was not probed: {second.fake.frames()}"
            assert second.fake.frames()[:3] == ["#stop!", "#crcoff!", "#qd!"]
            assert await rov.depth_cm() == 123
    finally:
        first.close()
        if second is not None:
            second.close()


@pytest.mark.realtime
def test_close_while_a_reopened_link_takes_nothing_returns_at_once_and_lets_the_port_go(
    reopened: list[FakeController], stuck: _StuckLines
) -> None:
    # Before, close() waited 2 s for the reconnecting thread, blocked in writing zero thrust to
    # a reopened link that took nothing, and returned with that thread still running and the
    # port still open (P22: the program's next open of it could fail).
    first, host_end = FakeController.on_socketpair()
    reopened.append(first)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, boot_timeout_s=2.0, on_event=events.append)
    rov = Client(SocketLink(host_end, "socket pair"), options, reopen=stuck.open)
    try:
        rov.start()
        rov.move(90, 50)  # a reopened link is sent zero thrust first
        first.close()
        assert wait_until(lambda: bool(stuck.far_ends))
        reconnector = rov._reconnector
        assert reconnector is not None
        started = time.monotonic()
        rov.close()
        took_s = time.monotonic() - started
        assert took_s < PROMPT_S, f"close() took {took_s:.2f} s"
        reconnector.join(PROMPT_S)
        assert not reconnector.is_alive()
        assert stuck.far_ends[0].fileno() >= 0
        assert stuck.first_was_let_go()
    finally:
        rov.close()


def test_a_command_that_waited_for_the_reopened_link_is_not_sent_after_a_stop(
    port: FakeControllerServer,
) -> None:
    # Before, a start() that waited for the reopened link went out after the stop() another
    # thread called meanwhile: the stop went first, and the robot was unlocked again after it.
    events: list[ClientEvent] = []
    with rovlink.connect(
        port.url, reconnect=True, keepalive=None, timeout=2.0, on_event=events.append
    ) as rov:
        rov.start()
        port.refuse = True  # unplugged
        port.fakes[0].close()
        assert wait_until(lambda: _lost(events))
        starting = ThreadCall(rov.start)  # waits for the link
        assert wait_until(lambda: rov._waiting_callers > 0)
        setting = ThreadCall(
            lambda: rov.set_max_pwm(180)
        )  # waits too; it neither moves nor unlocks
        assert wait_until(lambda: rov._waiting_callers > 1)
        rov.stop()  # (after both were asked for)
        port.refuse = False  # plugged back
        assert starting.done.wait(CONDITION_TIMEOUT_S)
        assert setting.done.wait(CONDITION_TIMEOUT_S)
        assert isinstance(starting.error, SupersededByStopError)
        assert setting.error is None
        assert rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert "#start!" not in frames
        assert "#mgmp.180!" in frames


def test_a_port_reopened_as_close_begins_is_let_go_untouched(
    reopened: list[FakeController],
) -> None:
    # Before, a port whose opening ended after close() had begun was written to (zero thrust)
    # and probed before the reconnecting thread noticed the close.
    first, host_end = FakeController.on_socketpair()
    reopened.append(first)
    clients: list[Client] = []
    opening = threading.Event()

    def reopen() -> Link:
        opening.set()
        wait_until(lambda: clients[0]._closing)  # opening takes until close() begins
        fake, ours = FakeController.on_socketpair()
        reopened.append(fake)
        return SocketLink(ours, "socket pair, reopened")

    events: list[ClientEvent] = []
    options = client_options(reconnect=True, boot_timeout_s=2.0, on_event=events.append)
    rov = Client(SocketLink(host_end, "socket pair"), options, reopen=reopen)
    clients.append(rov)
    try:
        rov.start()
        rov.move(90, 50)  # a reopened link is sent zero thrust first
        first.close()
        assert opening.wait(CONDITION_TIMEOUT_S)
    finally:
        rov.close()
    assert len(reopened) == 2
    late = reopened[1]
    assert late.wait_for(lambda fake: fake._fd < 0, CONDITION_TIMEOUT_S)  # let go
    assert late.raw == b""  # untouched


@pytest.mark.realtime
def test_a_stop_while_the_reopened_link_takes_nothing_returns_at_once(
    reopened: list[FakeController], stuck: _StuckLines, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, stop() waited behind the zero thrust the reconnecting thread was writing on a
    # reopened link that took nothing, until that write gave up (2 s).
    monkeypatch.setattr(links, "WRITE_TIMEOUT_S", 1.0)

    def reopen() -> Link:
        if stuck.far_ends:  # the next time: a controller that reads
            fake, ours = FakeController.on_socketpair()
            reopened.append(fake)
            return SocketLink(ours, "socket pair, reopened")
        return stuck.open()  # plugged back, but nothing reads it

    first, host_end = FakeController.on_socketpair()
    reopened.append(first)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, boot_timeout_s=2.0, on_event=events.append)
    rov = Client(SocketLink(host_end, "socket pair"), options, reopen=reopen)
    try:
        rov.start()
        rov.move(90, 50)  # a reopened link is sent zero thrust first
        first.close()
        assert wait_until(lambda: bool(stuck.far_ends))
        assert wait_until(lambda: rov._readied_link is not None)  # its zero thrust waits
        started = time.monotonic()
        rov.stop()
        took_s = time.monotonic() - started
        assert took_s < PROMPT_S, f"stop() took {took_s:.2f} s"
        # The stuck link gave up, and the next one begins with the stop.
        assert wait_until(lambda: len(reopened) == 2)
        assert reopened[1].wait_for(_probed, CONDITION_TIMEOUT_S)
        assert reopened[1].frames()[:3] == ["#stop!", "#crcoff!", "#qd!"]
    finally:
        rov.close()


@pytest.mark.realtime
def test_close_as_a_reopened_port_becomes_the_link_being_readied_lets_it_go_at_once(
    reopened: list[FakeController], stuck: _StuckLines
) -> None:
    # Before, a close() that began after the port was reopened, but before the reconnecting
    # thread took it as the link being readied, did not give up that link's writes: the
    # reconnecting thread wrote zero thrust to a line that took nothing, close() waited 2 s for
    # it and returned with that thread running and the port open.
    first, host_end = FakeController.on_socketpair()
    reopened.append(first)
    options = client_options(reconnect=True, boot_timeout_s=2.0)
    rov = Client(SocketLink(host_end, "socket pair"), options, reopen=stuck.open)
    readied_lock = WatchedLock(rov._readied_lock)
    rov._readied_lock = readied_lock  # type: ignore[assignment]
    try:
        rov.start()
        rov.move(90, 50)  # a reopened link is sent zero thrust first
        readied_lock.acquire()  # (the reconnecting thread waits for it once the port is open)
        try:
            first.close()
            assert wait_until(lambda: readied_lock.waiting == 1)
            reconnector = rov._reconnector
            assert reconnector is not None
            started = time.monotonic()
            closing = ThreadCall(rov.close)
            assert wait_until(lambda: rov._closing)
        finally:
            readied_lock.release()
        assert closing.done.wait(CONDITION_TIMEOUT_S)
        took_s = time.monotonic() - started
        assert took_s < PROMPT_S, f"close() took {took_s:.2f} s"
        reconnector.join(PROMPT_S)
        assert not reconnector.is_alive()
        assert stuck.first_was_let_go()
    finally:
        rov.close()


@pytest.mark.parametrize("wrapped", [False, True], ids=["serial", "spy"])
def test_a_write_waiting_on_a_pyserial_port_is_given_up_at_once(
    tmp_path: Path, wrapped: bool
) -> None:
    # spy:// (pyserial's logging wrapper) is read and written through pyserial, not through
    # the descriptor: its waiting write could not be given up, and a reconnection waited the
    # 2 s write timeout for it. pyserial's cancel_write ends it, and reports it written.
    # (pyserial waits for room only once its write has begun: a write that finds none at all
    # retries until its write timeout, which no cancel ends.)
    controller_end, terminal = os.openpty()  # the controller end reads nothing
    tty.setraw(terminal)
    name = os.ttyname(terminal)
    url = f"spy://{name}?file={tmp_path / 'spy.txt'}" if wrapped else name
    link = links.open_link(parse_url(url))
    try:
        assert isinstance(link, (links.PortLink, links.FdLink))
        assert isinstance(link, links.PortLink) == wrapped  # (read and written by pyserial)
        # More than a terminal holds (20 KiB here), not so much that spy:// takes long to log it.
        writer = ThreadCall(lambda: link.write(b"\r\n" * (1 << 15)))
        # (Bytes reach the controller end as the write starts; it then waits for room.)
        assert wait_until(
            lambda: writer.done.is_set() or bool(select.select([controller_end], [], [], 0)[0])
        )
        assert not writer.done.is_set(), f"the write ended before it was given up: {writer.error!r}"
        started = time.monotonic()
        link.abort_writes()
        assert writer.done.wait(PROMPT_S), "the waiting write was not given up"
        assert time.monotonic() - started < PROMPT_S
        assert isinstance(writer.error, ConnectionLostError)
        assert "write abandoned" in str(writer.error)
        with pytest.raises(ConnectionLostError, match="write abandoned"):
            link.write(b"#stop!")  # (the link is lost: the stop goes on the next one)
    finally:
        link.close()
        os.close(terminal)
        os.close(controller_end)
