"""On a serial line, a client sends no faster than the line carries: a program that loops on
``move`` would otherwise fill the kernel's buffer (4 KB, seconds of a slow line) and a ``#stop!``
would wait behind all of it. A stop itself never waits for the line."""

from __future__ import annotations

import asyncio
import socket
import threading
import time
from collections.abc import Hashable, Iterator

import pytest
import serial

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import Client, SupersededByStopError
from rovlink.client.links import MAX_QUEUED_LINE_S, SerialFdLink, SocketLink, queued_line_s
from rovlink.protocol import Command
from rovlink.sim.server import SimServer
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    ThreadCall,
    client_options,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController

BAUD = 9600  # 1.04 ms a byte: "#th.90.30!" takes 10.4 ms on the line
MOVES = 50  # half a second of the line, written back to back
#: How late the controller may see a #stop! sent after the moves: the line time allowed ahead
#: of a frame, the #stop!'s own, and the simulator's and the scheduler's latency. Unpaced, the
#: moves' half second of line time was ahead of it.
STOP_LATENCY_LIMIT_S = 0.2


class _ServedSim:
    """A simulated controller at ``BAUD`` on a pseudo-terminal, and when it saw each frame."""

    def __init__(self) -> None:
        self.server = SimServer(seed=1, baud=BAUD)
        self.path = self.server.open_pty()
        self.stop_seen_at_s: float | None = None
        received = bytearray()  # (the line hands the controller a byte or a few at a time)
        receive = self.server.robot.receive

        def watched_receive(data: bytes, line: Hashable = None) -> None:
            received.extend(data)
            if self.stop_seen_at_s is None and b"#stop!" in received[-len(data) - 6 :]:
                self.stop_seen_at_s = time.monotonic()
            receive(data, line)

        self.server.robot.receive = watched_receive  # type: ignore[method-assign]
        self._ending = threading.Event()
        self._thread = threading.Thread(
            target=self.server.serve, args=(self._ending.is_set,), daemon=True
        )
        self._thread.start()

    @property
    def url(self) -> str:
        return f"{self.path}?baudrate={BAUD}"

    def close(self) -> None:
        self._ending.set()
        self._thread.join(CONDITION_TIMEOUT_S)
        self.server.close()


@pytest.fixture
def sim() -> Iterator[_ServedSim]:
    served = _ServedSim()
    yield served
    served.close()


def _stop_latency_s(sim: _ServedSim, stop_called_at_s: float) -> float:
    assert wait_until(lambda: sim.stop_seen_at_s is not None, timeout_s=5.0)
    assert sim.stop_seen_at_s is not None
    return sim.stop_seen_at_s - stop_called_at_s


@pytest.mark.integration
def test_a_stop_after_a_burst_of_moves_reaches_the_controller_at_once(sim: _ServedSim) -> None:
    # Before, the fifty moves went into the kernel at once and the #stop! reached the
    # controller 0.5 s after stop() returned, behind them.
    with rovlink.connect(sim.url, keepalive=None) as rov:
        rov.start()
        for number in range(MOVES):
            rov.move(90, number % 50)
        stop_called_at_s = time.monotonic()
        rov.stop()
        assert _stop_latency_s(sim, stop_called_at_s) < STOP_LATENCY_LIMIT_S


@pytest.mark.integration
def test_asyncio_a_stop_after_a_burst_of_moves_reaches_the_controller_at_once(
    sim: _ServedSim,
) -> None:
    async def fly() -> float:
        async with rovlink.aio.connect(sim.url, keepalive=None) as rov:
            await rov.start()
            for number in range(MOVES):
                await rov.move(90, number % 50)
            stop_called_at_s = time.monotonic()
            await rov.stop()
            return stop_called_at_s

    stop_called_at_s = asyncio.run(fly())
    assert _stop_latency_s(sim, stop_called_at_s) < STOP_LATENCY_LIMIT_S


@pytest.mark.integration
@pytest.mark.realtime
def test_a_serial_link_times_what_it_wrote_at_its_baud_rate(sim: _ServedSim) -> None:
    port = serial.Serial(sim.path, BAUD, timeout=0, exclusive=True)
    link = SerialFdLink(port, "pty")
    try:
        assert queued_line_s(link) == link.queued_s
        assert link.queued_s() == 0.0
        link.write(b"#mgmp.180!" * 10)  # 100 bytes: 0.104 s at 9600 baud
        queued_s = link.queued_s()
        assert 0.05 < queued_s <= 100 * 10 / BAUD
        assert wait_until(lambda: link.queued_s() == 0.0, timeout_s=1.0)
    finally:
        link.close()


def test_a_link_without_a_line_rate_is_not_paced() -> None:
    # (TCP: the network's rate is unknown, and a socket's buffer is not a line's.)
    near, far = socket.socketpair()
    try:
        assert queued_line_s(SocketLink(near, "socket pair")) is None
    finally:
        near.close()
        far.close()


class _BackloggedLink(SocketLink):
    """A socket link whose line, the test says, has ``backlog_s`` of bytes queued."""

    def __init__(self, sock: socket.socket, description: str) -> None:
        super().__init__(sock, description)
        self.backlog_s = 0.0
        self.asked = threading.Event()  # a sender looked at the line while it was behind

    def queued_s(self) -> float:
        if self.backlog_s:
            self.asked.set()
        return self.backlog_s


@pytest.fixture
def backlogged() -> Iterator[tuple[FakeController, _BackloggedLink]]:
    fake, host_end = FakeController.on_socketpair()
    yield fake, _BackloggedLink(host_end, "socket pair, backlogged")
    fake.close()


def test_a_move_waiting_for_the_line_is_superseded_by_a_stop_which_does_not_wait(
    backlogged: tuple[FakeController, _BackloggedLink],
) -> None:
    fake, link = backlogged
    rov = Client(link, client_options())
    try:
        rov.start()
        link.backlog_s = MAX_QUEUED_LINE_S + 0.03  # (the waiting move looks again every 30 ms)
        moving = ThreadCall(lambda: rov.move(90, 50))
        setting = ThreadCall(lambda: rov.set_max_pwm(180))  # neither moves nor unlocks
        assert link.asked.wait(CONDITION_TIMEOUT_S)
        rov.stop()  # the line is still behind: it goes all the same
        assert fake.wait_for(lambda f: "#stop!" in f.frames())
        assert not moving.done.is_set()
        link.backlog_s = 0.0
        assert moving.done.wait(CONDITION_TIMEOUT_S)
        assert setting.done.wait(CONDITION_TIMEOUT_S)
        assert isinstance(moving.error, SupersededByStopError)
        assert setting.error is None
        assert fake.wait_for(lambda f: "#mgmp.180!" in f.frames())
        assert "#th.90.50!" not in fake.frames()
    finally:
        link.backlog_s = 0.0
        rov.close()


async def test_asyncio_a_move_waiting_for_the_line_is_superseded_by_a_stop() -> None:
    fake, host_end = FakeController.on_socketpair()
    link = _BackloggedLink(host_end, "socket pair, backlogged")
    rov = await AsyncClient(link, client_options()).open()
    try:
        await rov.start()
        link.backlog_s = MAX_QUEUED_LINE_S + 0.03
        moving = asyncio.ensure_future(rov.move(90, 50))
        setting = asyncio.ensure_future(rov.set_max_pwm(180))
        assert await wait_until_async(link.asked.is_set)
        await rov.stop()
        assert await wait_until_async(lambda: "#stop!" in fake.frames())
        assert not moving.done()
        link.backlog_s = 0.0
        with pytest.raises(SupersededByStopError, match=r"#th\.90\.50!"):
            await asyncio.wait_for(moving, CONDITION_TIMEOUT_S)
        await asyncio.wait_for(setting, CONDITION_TIMEOUT_S)
        assert await wait_until_async(lambda: "#mgmp.180!" in fake.frames())
        assert "#th.90.50!" not in fake.frames()
    finally:
        link.backlog_s = 0.0
        await rov.close()
        fake.close()


# -- raw frames and send(Command) go as the command methods do -------------------------------


def _move_of(number: int, how: str) -> object:
    return f"#th.90.{number % 50}!" if how == "send_raw" else Command("th", (90, number % 50))


@pytest.mark.integration
@pytest.mark.parametrize(("how", "stop_how"), [("send_raw", "stop"), ("send_raw", "raw #stop!")])
def test_a_stop_after_a_burst_of_raw_moves_reaches_the_controller_at_once(
    sim: _ServedSim, how: str, stop_how: str
) -> None:
    # Before, send_raw frames went into the kernel unpaced: the #stop! reached the controller
    # half a second after it was sent, behind fifty moves.
    with rovlink.connect(sim.url, keepalive=None) as rov:
        rov.start()
        send = getattr(rov, how)
        for number in range(MOVES):
            send(_move_of(number, how))
        stop_called_at_s = time.monotonic()
        rov.stop() if stop_how == "stop" else rov.send_raw("#stop!")
        assert _stop_latency_s(sim, stop_called_at_s) < STOP_LATENCY_LIMIT_S


@pytest.mark.integration
@pytest.mark.parametrize(("how", "stop_how"), [("send_raw", "stop"), ("send", "raw #stop!")])
def test_asyncio_a_stop_after_a_burst_of_raw_moves_reaches_the_controller_at_once(
    sim: _ServedSim, how: str, stop_how: str
) -> None:
    # Before, neither raw frames nor send(Command) were paced by the asyncio client (the
    # blocking client's send(Command) was).
    async def fly() -> float:
        async with rovlink.aio.connect(sim.url, keepalive=None) as rov:
            await rov.start()
            send = getattr(rov, how)
            for number in range(MOVES):
                await send(_move_of(number, how))
            stop_called_at_s = time.monotonic()
            await (rov.stop() if stop_how == "stop" else rov.send_raw("#stop!"))
            return stop_called_at_s

    stop_called_at_s = asyncio.run(fly())
    assert _stop_latency_s(sim, stop_called_at_s) < STOP_LATENCY_LIMIT_S


def test_a_raw_move_waiting_for_the_line_is_superseded_by_a_raw_stop_which_does_not_wait(
    backlogged: tuple[FakeController, _BackloggedLink],
) -> None:
    fake, link = backlogged
    rov = Client(link, client_options())
    try:
        rov.start()
        link.backlog_s = MAX_QUEUED_LINE_S + 0.03
        moving = ThreadCall(lambda: rov.send_raw("#th.90.50!"))
        assert link.asked.wait(CONDITION_TIMEOUT_S)
        assert rov.send_raw("#qd!")[0].name == "qd"  # a query does not wait for the line
        rov.send_raw("#stop!")  # the line is still behind: it goes all the same
        assert fake.wait_for(lambda f: "#stop!" in f.frames())
        assert not moving.done.is_set()
        link.backlog_s = 0.0
        assert moving.done.wait(CONDITION_TIMEOUT_S)
        assert isinstance(moving.error, SupersededByStopError)
        assert "#th.90.50!" not in fake.frames()
    finally:
        link.backlog_s = 0.0
        rov.close()


async def test_asyncio_a_raw_move_waiting_for_the_line_is_superseded_by_a_raw_stop() -> None:
    fake, host_end = FakeController.on_socketpair()
    link = _BackloggedLink(host_end, "socket pair, backlogged")
    rov = await AsyncClient(link, client_options()).open()
    try:
        await rov.start()
        link.backlog_s = MAX_QUEUED_LINE_S + 0.03
        moving = asyncio.ensure_future(rov.send_raw("#th.90.50!"))
        assert await wait_until_async(link.asked.is_set)
        assert (await rov.send_raw("#qd!"))[0].name == "qd"  # a query does not wait
        await rov.send_raw("#stop!")
        assert await wait_until_async(lambda: "#stop!" in fake.frames())
        assert not moving.done()
        link.backlog_s = 0.0
        with pytest.raises(SupersededByStopError, match=r"#th\.90\.50!"):
            await asyncio.wait_for(moving, CONDITION_TIMEOUT_S)
        assert "#th.90.50!" not in fake.frames()
    finally:
        link.backlog_s = 0.0
        await rov.close()
        fake.close()
