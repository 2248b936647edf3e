"""The asyncio client's connection going wrong: an open that fails or is cancelled, a link lost
while a call waits for a checksum switch, a reopened link that fails at once, and close() while
the client reconnects. Nothing may hang, leak a port, or leave the loop watching a descriptor.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading
from collections.abc import Iterator

import pytest

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient, ConnectError, ConnectionLostError
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.links import Link, SocketLink
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    NO_REPLY_TIMEOUT_S,
    REPLY_TIMEOUT_S,
    client_options,
    wait_until_async,
)
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = pytest.mark.integration


@pytest.fixture
def servers() -> Iterator[list[FakeControllerServer]]:
    made: list[FakeControllerServer] = []
    yield made
    for server in made:
        server.close()


async def test_a_failed_connect_leaves_the_next_connect_working(
    servers: list[FakeControllerServer],
) -> None:
    """Before the fix a connect that timed out waiting for the controller (or was cancelled)
    closed its socket but left the loop watching the descriptor: the next connection, given
    the same descriptor number, was never read and failed as "did not answer"."""
    booting, ready = FakeControllerServer(boot_s=30.0), FakeControllerServer()
    servers += [booting, ready]
    with pytest.raises(ConnectError, match="did not answer"):
        await rovlink.aio.connect(booting.url, boot_timeout=0.3)
    with pytest.raises((TimeoutError, asyncio.TimeoutError)):
        await asyncio.wait_for(rovlink.aio.connect(booting.url, boot_timeout=10.0), 0.3)
    async with rovlink.aio.connect(ready.url, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        assert await rov.depth_cm() == 123


@pytest.mark.parametrize("how", ["boot timeout", "cancelled", "wrong algorithm"])
async def test_an_open_that_fails_stops_watching_the_port(how: str) -> None:
    fake, sock = FakeController.on_socketpair(
        boot_s=30.0 if how != "wrong algorithm" else 0.0, algorithm="xor"
    )
    fd = sock.fileno()
    client = AsyncClient(
        SocketLink(sock, "socket pair"),
        client_options(
            boot_timeout_s=0.3 if how != "cancelled" else 10.0,
            checksum=True,
            timeout_s=NO_REPLY_TIMEOUT_S,  # (the wrong algorithm's replies never match)
        ),
    )
    try:
        if how == "cancelled":
            with pytest.raises((TimeoutError, asyncio.TimeoutError)):
                await asyncio.wait_for(client.open(), 0.2)
        else:
            with pytest.raises(ConnectError):
                await client.open()
        loop = asyncio.get_running_loop()
        assert not loop.remove_reader(fd), "the loop still watches the port of a failed open"
        assert client.closed
        assert client._timer is None
        assert sock.fileno() == -1
        await asyncio.wait_for(client.close(), CONDITION_TIMEOUT_S)
    finally:
        fake.close()


async def test_send_raw_waiting_for_a_checksum_switch_fails_when_the_link_is_lost() -> None:
    """A raw query that waited for a checksum switch while the TCP link was lost raises
    ConnectionLostError; before the fix it was queued on the dead link (a write to a peer that
    has closed still succeeds) and waited for ever."""
    server = socket.create_server(("127.0.0.1", 0))
    host_end = socket.create_connection(server.getsockname())
    controller_end, _ = server.accept()
    server.close()
    fake = FakeController(controller_end.detach())
    client = await AsyncClient(SocketLink(host_end, "tcp"), client_options(retries=0)).open()
    try:
        fake.then("drop")
        on_the_wire = asyncio.ensure_future(client.depth_cm())
        assert await asyncio.to_thread(fake.wait_for, lambda f: "#qd!" in f.frames())
        switch = asyncio.ensure_future(client.set_checksum(True))  # waits for that reply
        await asyncio.sleep(0)
        raw = asyncio.ensure_future(client.send_raw("#qhe!"))  # waits for the switch
        await asyncio.sleep(0)
        fake.close()  # the controller goes away (FIN)
        for call in (on_the_wire, switch):
            with pytest.raises(ConnectionLostError):
                await call
        try:
            await asyncio.wait_for(raw, CONDITION_TIMEOUT_S)
        except ConnectionLostError:
            pass
        except (TimeoutError, asyncio.TimeoutError):
            pytest.fail("send_raw queued its query on the lost link and never returned")
        assert client._session.pending == ()
    finally:
        await client.close()
        fake.close()


class _BusyServer:
    """A TCP port whose every connection is told it is busy, then closed (a second client of
    ``rovlink sim --tcp``, a serial-to-network bridge that serves one client)."""

    SAYS = b"busy: the controller already has a client\r\n"

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._server.getsockname()[1]}"
        self.connections = 0
        threading.Thread(target=self._serve, name="busy server", daemon=True).start()

    def _serve(self) -> None:
        while True:
            try:
                connection, _ = self._server.accept()
            except OSError:
                return
            self.connections += 1
            with connection:
                connection.sendall(self.SAYS)
                connection.shutdown(socket.SHUT_WR)
                # Read on until the client lets go: closed with its probe unread, the
                # connection would be reset, and the client would read that rather than the end.
                connection.settimeout(CONDITION_TIMEOUT_S)
                with contextlib.suppress(OSError):
                    while connection.recv(1024):
                        pass

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._server.shutdown(socket.SHUT_RDWR)
        self._server.close()


@pytest.mark.parametrize("reconnect", [False, True])
async def test_a_link_closed_while_connecting_is_a_connect_error_as_the_blocking_clients(
    reconnect: bool,
) -> None:
    """Before, with ``reconnect=True`` the asyncio client began reconnecting while it was still
    connecting: it opened the port again and again, and the connect failed after a quarter of a
    second with "ConnectionLostError: …: lost, reconnecting", not what the controller said;
    without it, the ConnectError read "connection lost: …", unlike the blocking client's."""
    server = _BusyServer()
    try:
        with pytest.raises(ConnectError) as blocking:
            await asyncio.to_thread(rovlink.connect, server.url, reconnect=reconnect)
        assert str(blocking.value).endswith(
            '; it said: "busy: the controller already has a client"'
        )
        with pytest.raises(ConnectError) as native:
            await rovlink.aio.connect(server.url, reconnect=reconnect)
        assert str(native.value) == str(blocking.value)
        assert server.connections == 2  # one each: nothing was reopened
        # (A wait the connect gave up on ends at the loop's next turn: one turn, then no task
        # but this one, none reopening the link.)
        await asyncio.sleep(0)
        assert asyncio.all_tasks() == {asyncio.current_task()}
    finally:
        server.close()


async def test_a_reopened_link_that_fails_at_once_is_one_failed_attempt() -> None:
    """Before the fix a reopened port that failed when the checksum mode was written to it
    ended the reconnection for good: the task died with the error, and every later call
    raised "not reopened"."""
    fakes: list[FakeController] = []
    attempts: list[str] = []

    def reopen() -> Link:
        attempts.append("reopen")
        if len(attempts) == 1:  # plugged into nothing: the first write fails (EPIPE)
            host_end, gone = socket.socketpair()
            gone.close()
            return SocketLink(host_end, "dead socket pair")
        fake, host_end = FakeController.on_socketpair()
        fakes.append(fake)
        return SocketLink(host_end, "socket pair")

    first, host_end = FakeController.on_socketpair()
    fakes.append(first)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, on_event=events.append)
    client = await AsyncClient(SocketLink(host_end, "socket pair"), options, reopen=reopen).open()
    try:
        assert await client.depth_cm() == 123
        first.close()  # unplugged
        assert await wait_until_async(
            lambda: any(isinstance(e, LinkState) and e.state == "reconnected" for e in events)
        ), f"never reconnected after {len(attempts)} attempts; reconnector: {client._reconnector}"
        assert len(attempts) == 2
        assert await client.heading_deg() == 275
        assert fakes[-1].frames()[:1] == ["#crcoff!"]  # the mode was restored on the new link
    finally:
        await client.close()
        for fake in fakes:
            fake.close()


async def test_a_reopened_link_lost_while_it_is_readied_is_one_failed_attempt() -> None:
    """A reopened TCP link that answers the readiness probe and closes: before the fix the loss
    was ignored, the client reported "reconnected" on a link nobody read any more, and the next
    call failed (or timed out) instead of waiting for the real reconnection."""
    server = socket.create_server(("127.0.0.1", 0))
    address = server.getsockname()
    fakes: list[FakeController] = []
    attempts: list[str] = []

    def answer_then_close() -> None:
        connection, _ = server.accept()
        with connection:
            received = b""
            while b"#qd!" not in received:
                received += connection.recv(64)
            connection.sendall(b"$qd.5!")

    def reopen() -> Link:
        attempts.append("reopen")
        if len(attempts) == 1:  # a board that answers once and goes away
            threading.Thread(target=answer_then_close, daemon=True).start()
            return SocketLink(socket.create_connection(address), "tcp, going away")
        fake, host_end = FakeController.on_socketpair()
        fakes.append(fake)
        return SocketLink(host_end, "socket pair")

    first, host_end = FakeController.on_socketpair()
    fakes.append(first)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, boot_timeout_s=2.0, on_event=events.append)
    client = await AsyncClient(SocketLink(host_end, "socket pair"), options, reopen=reopen).open()
    try:
        first.close()
        assert await wait_until_async(lambda: len(attempts) == 2), "no second attempt"
        assert await client.heading_deg() == 275
        states = [event.state for event in events if isinstance(event, LinkState)]
        assert states == ["lost", "reconnected"]
    finally:
        await client.close()
        server.close()
        for fake in fakes:
            fake.close()


async def test_close_while_reconnecting_fails_waiting_calls_at_once_and_closes_a_late_port() -> (
    None
):
    """Before the fix a call waiting for the reconnection waited its whole timeout after
    close(), and a port whose reopening finished after close() stayed open."""
    release = threading.Event()
    reopened: list[tuple[FakeController, SocketLink]] = []

    def reopen() -> Link:
        release.wait(CONDITION_TIMEOUT_S)  # the adapter takes its time to come back
        fake, host_end = FakeController.on_socketpair()
        link = SocketLink(host_end, "socket pair, reopened")
        reopened.append((fake, link))
        return link

    first, host_end = FakeController.on_socketpair()
    options = client_options(reconnect=True, timeout_s=30.0)
    client = await AsyncClient(SocketLink(host_end, "socket pair"), options, reopen=reopen).open()
    try:
        assert await client.depth_cm() == 123
        first.close()
        assert await wait_until_async(lambda: not client._link_ready.is_set())
        waiting = asyncio.ensure_future(client.depth_cm())  # waits for the link (30 s)
        await asyncio.sleep(0.01)
        assert not waiting.done()
        await asyncio.wait_for(client.close(), CONDITION_TIMEOUT_S)
        with pytest.raises(ConnectionLostError):
            await asyncio.wait_for(waiting, CONDITION_TIMEOUT_S)
        release.set()
        assert await wait_until_async(lambda: len(reopened) == 1)
        assert await wait_until_async(lambda: reopened[0][1]._closed), "the late port leaked"
    finally:
        release.set()
        first.close()
        for fake, link in reopened:
            link.close()
            fake.close()


def test_asyncio_run_takes_a_connect_as_its_coroutine() -> None:
    # As close()'s docstring shows: before, asyncio.run (and create_task) refused it, "a
    # coroutine was expected, got <rovlink.aio.client._Connecting object …>".
    rov = asyncio.run(rovlink.aio.connect("sim://"))
    assert isinstance(rov, rovlink.aio.AsyncClient)
    asyncio.run(rov.close())
    assert rov.closed


async def test_a_connect_may_be_a_task_of_its_own() -> None:
    rov = await asyncio.create_task(rovlink.aio.connect("sim://"))
    try:
        assert await rov.depth_cm() == 0
    finally:
        await rov.close()
