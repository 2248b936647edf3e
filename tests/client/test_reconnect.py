"""reconnect=True: a lost link (an adapter unplugged and plugged back) is reopened and reused."""

from __future__ import annotations

import asyncio
import threading

import pytest

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import Client
from rovlink.client.errors import ConnectionLostError
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.links import Link, SocketLink
from rovlink.client.readiness import PROBE_BYTES
from rovlink.protocol import Response
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    client_options,
    wait_until,
    wait_until_async,
)
from tests.client.fake_controller import FakeController, FakeControllerServer

pytestmark = pytest.mark.integration


def test_a_lost_link_is_reopened_and_the_checksum_mode_restored(port: FakeControllerServer) -> None:
    events: list[ClientEvent] = []
    with rovlink.connect(
        port.url, reconnect=True, checksum=True, keepalive=0.1, timeout=2.0, on_event=events.append
    ) as rov:
        assert rov.depth_cm() == 123
        port.refuse = True  # unplugged: the first attempts to reopen fail
        port.fakes[0].close()
        assert wait_until(
            lambda: any(isinstance(event, LinkState) and event.state == "lost" for event in events)
        )
        port.refuse = False  # plugged back
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.heading_deg() == 275  # waits for the reconnection, then goes on
        assert port.fakes[1].decoder.checksum_enabled  # the mode is the one asked for
        assert not rov.closed
    states = [event.state for event in events if isinstance(event, LinkState)]
    assert states == ["lost", "reconnected"]


def test_without_reconnect_a_lost_link_is_final(port: FakeControllerServer) -> None:
    with rovlink.connect(port.url, keepalive=0.1, timeout=2.0) as rov:
        assert rov.depth_cm() == 123
        port.fakes[0].close()
        assert wait_until(lambda: rov.closed)
        with pytest.raises(ConnectionLostError):
            rov.depth_cm()


async def test_the_asyncio_client_reopens_a_lost_link_too(port: FakeControllerServer) -> None:
    events: list[ClientEvent] = []
    async with rovlink.aio.connect(
        port.url, reconnect=True, checksum=True, timeout=2.0, on_event=events.append
    ) as rov:
        assert await rov.depth_cm() == 123
        port.fakes[0].close()
        assert await wait_until_async(lambda: len(port.fakes) == 2)
        assert await rov.heading_deg() == 275  # waits for the reconnection, then goes on
        assert port.fakes[1].decoder.checksum_enabled
        assert not rov.closed
    states = [event.state for event in events if isinstance(event, LinkState)]
    assert states == ["lost", "reconnected"]


def _after_readiness_probe(frames: list[str]) -> list[str]:
    """The frames a client sent on a reopened link once the controller answered its probe."""
    start = frames.index("#crcoff!")
    assert frames[start : start + 2] == ["#crcoff!", "#qd!"]
    return frames[start + 2 :]


def test_motion_is_zeroed_first_on_a_reopened_link(port: FakeControllerServer) -> None:
    # Only the link dropped: the controller may still drive the last thrust, and the probes
    # and queries that follow would feed its watchdog (P17). Zero thrust goes first on the new
    # link, before the probe (before, only after it), and again once the mode is restored.
    with rovlink.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        rov.start()
        rov.move(90, 50)
        rov.set_vertical_thrust(-30)
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert frames[:4] == ["#th.90.0!", "#mvs.+0!", "#crcoff!", "#qd!"]
        assert _after_readiness_probe(frames)[:3] == ["#crcoff!", "#th.90.0!", "#mvs.+0!"]


def test_a_slow_controller_gets_zero_thrust_before_any_probe(port: FakeControllerServer) -> None:
    # The reopened link's controller does not take its input at once (a serial bridge that
    # restarts): the probes, every 0.25 s, would keep its watchdog fed while it drives on.
    port.boot_s = 0.6
    with rovlink.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        rov.start()
        rov.move(45, 50)
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.depth_cm() == 123
        assert bytes(port.fakes[1].ignored).startswith(b"#th.45.0!#crcoff!#qd!")


def test_zero_thrust_reaches_a_controller_still_in_checksum_mode(
    port: FakeControllerServer,
) -> None:
    # Before, the zero thrust went out checksummed after the probe's #crcoff! had put the
    # controller in plain mode, and before #crcon!: the controller dropped it.
    with rovlink.connect(
        port.url, reconnect=True, checksum=True, keepalive=None, timeout=2.0
    ) as rov:
        rov.start()
        rov.move(90, 50)
        port.checksum_on_accept = True  # only the link drops: the board runs on
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert frames[0] == "#th.90.0!"  # taken in checksum mode, before the probe
        assert _after_readiness_probe(frames)[:2] == ["#crcon!", "#th.90.0!"]
        assert not port.fakes[1].bad_frames


def test_a_link_reopened_at_rest_gets_no_zero_thrust(port: FakeControllerServer) -> None:
    with rovlink.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        rov.start()
        rov.move(90, 50)
        rov.move(90, 0)
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.depth_cm() == 123
        assert not any(frame.startswith(("#th", "#mvs")) for frame in port.fakes[1].frames())


async def test_the_asyncio_client_zeroes_motion_first_on_a_reopened_link(
    port: FakeControllerServer,
) -> None:
    async with rovlink.aio.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        await rov.start()
        await rov.move(270, 40)
        port.fakes[0].close()
        assert await wait_until_async(lambda: len(port.fakes) == 2)
        assert await rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert frames[:3] == ["#th.270.0!", "#crcoff!", "#qd!"]
        assert _after_readiness_probe(frames)[:2] == ["#crcoff!", "#th.270.0!"]


async def test_the_asyncio_client_zeroes_motion_for_a_controller_in_checksum_mode(
    port: FakeControllerServer,
) -> None:
    async with rovlink.aio.connect(
        port.url, reconnect=True, checksum=True, keepalive=None, timeout=2.0
    ) as rov:
        await rov.start()
        await rov.move(270, 40)
        port.checksum_on_accept = True
        port.fakes[0].close()
        assert await wait_until_async(lambda: len(port.fakes) == 2)
        assert await rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert frames[0] == "#th.270.0!"
        assert _after_readiness_probe(frames)[:2] == ["#crcon!", "#th.270.0!"]
        assert not port.fakes[1].bad_frames


@pytest.mark.parametrize("client", ["blocking", "asyncio"])
async def test_a_query_cut_by_the_loss_names_the_link_being_reopened(
    port: FakeControllerServer, client: str
) -> None:
    # (Before, the asyncio client said only "connection lost: closed".)
    if client == "blocking":
        with rovlink.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
            port.fakes[0].then("close")
            with pytest.raises(ConnectionLostError, match=r"127\.0\.0\.1.*lost, reconnecting"):
                rov.depth_cm()
        return
    async with rovlink.aio.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as arov:
        port.fakes[0].then("close")
        with pytest.raises(ConnectionLostError, match=r"127\.0\.0\.1.*lost, reconnecting"):
            await arov.depth_cm()


def _lost(events: list[ClientEvent]) -> bool:
    return any(isinstance(event, LinkState) and event.state == "lost" for event in events)


def test_a_stop_while_the_link_is_down_is_the_reopened_links_first_frame(
    port: FakeControllerServer,
) -> None:
    # Before, stop() waited `timeout` for the link and raised ConnectionLostError: the program's
    # #stop! was never sent, and the reopened link got zero thrust with the motors unlocked.
    events: list[ClientEvent] = []
    with rovlink.connect(
        port.url, reconnect=True, keepalive=None, timeout=2.0, on_event=events.append
    ) as rov:
        rov.start()
        rov.move(90, 50)
        port.refuse = True  # unplugged
        port.fakes[0].close()
        assert wait_until(lambda: _lost(events))
        rov.stop()
        port.refuse = False  # plugged back
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert frames[:3] == ["#stop!", "#crcoff!", "#qd!"]  # in place of zero thrust
        assert _after_readiness_probe(frames)[:2] == ["#crcoff!", "#stop!"]
        assert "#th.90.0!" not in frames


async def test_the_asyncio_client_keeps_a_stop_for_the_reopened_link_too(
    port: FakeControllerServer,
) -> None:
    # Before, stop() raised ConnectionLostError at once while the link was being reopened.
    events: list[ClientEvent] = []
    async with rovlink.aio.connect(
        port.url, reconnect=True, keepalive=None, timeout=2.0, on_event=events.append
    ) as rov:
        await rov.start()
        await rov.move(270, 40)
        port.refuse = True
        port.fakes[0].close()
        assert await wait_until_async(lambda: _lost(events))
        await rov.stop()
        port.refuse = False
        assert await wait_until_async(lambda: len(port.fakes) == 2)
        assert await rov.depth_cm() == 123
        frames = port.fakes[1].frames()
        assert frames[:3] == ["#stop!", "#crcoff!", "#qd!"]
        assert _after_readiness_probe(frames)[:2] == ["#crcoff!", "#stop!"]


def _probed(fake: FakeController) -> bool:
    return "#qd!" in fake.frames()


def _stopped(fake: FakeController) -> bool:
    return "#stop!" in fake.frames()


def test_a_stop_during_the_reopened_links_readiness_probe_goes_out_at_once(
    port: FakeControllerServer,
) -> None:
    # Before, the #stop! waited for the probe's answer: a controller slow to answer (a busy
    # board, a slow bridge) drove on meanwhile, the probes feeding its watchdog (P17).
    with rovlink.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        rov.start()
        rov.move(90, 50)
        port.script = ("hold",)  # the reopened link's controller holds its first answer
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)
        reopened = port.fakes[1]
        assert reopened.wait_for(_probed)  # the probe is out, its answer held
        rov.stop()
        assert reopened.wait_for(_stopped), f"no #stop! while probing: {reopened.frames()}"
        reopened.release()  # the probe is answered (only now): the link is ready
        assert rov.depth_cm() == 123
        frames = reopened.frames()
        assert frames[:3] == ["#th.90.0!", "#crcoff!", "#qd!"]
        stop = frames.index("#stop!")
        assert set(frames[3:stop]) <= {"#crcoff!", "#qd!"}  # probes only before it
        # Again once the controller answered (a board still booting loses its input, P21),
        # with the mode, before the program's query.
        assert frames[-3:] == ["#crcoff!", "#stop!", "#qd!"]


async def test_the_asyncio_client_sends_a_stop_during_the_readiness_probe_at_once(
    port: FakeControllerServer,
) -> None:
    async with rovlink.aio.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        await rov.start()
        await rov.move(270, 40)
        port.script = ("hold",)
        port.fakes[0].close()
        assert await wait_until_async(lambda: len(port.fakes) == 2)
        reopened = port.fakes[1]
        assert await asyncio.to_thread(reopened.wait_for, _probed)
        await rov.stop()
        stopped = await asyncio.to_thread(reopened.wait_for, _stopped)
        assert stopped, f"no #stop! while probing: {reopened.frames()}"
        reopened.release()
        assert await rov.depth_cm() == 123
        frames = reopened.frames()
        assert frames[:3] == ["#th.270.0!", "#crcoff!", "#qd!"]
        stop = frames.index("#stop!")
        assert set(frames[3:stop]) <= {"#crcoff!", "#qd!"}
        assert frames[-3:] == ["#crcoff!", "#stop!", "#qd!"]


class _LostWhenReady(SocketLink):
    """A reopened link unplugged right as the controller answered its readiness probe: the
    write that follows the probe (the checksum mode, then zero thrust or a stop) fails."""

    def send_some(self, data: bytes | bytearray | memoryview) -> int:
        if bytes(data).startswith(b"#crcoff!") and bytes(data) != PROBE_BYTES:
            raise ConnectionLostError(f"{self.description}: unplugged")
        return super().send_some(data)


@pytest.mark.parametrize("what", ["zero thrust", "stop"])
@pytest.mark.parametrize("client", ["blocking", "asyncio"])
async def test_a_reopened_link_lost_as_it_became_ready_leaves_the_next_one_its_first_frames(
    client: str, what: str
) -> None:
    # Before, the first reopened link's readying took the motion to rest and the stop as done
    # although they never left: the next link began with the probe, no zero thrust or #stop!.
    fakes: list[FakeController] = []
    plugged_back = threading.Event()

    def reopen() -> Link:
        plugged_back.wait(CONDITION_TIMEOUT_S)  # (the test's stop() comes while it is down)
        fake, host_end = FakeController.on_socketpair()
        fakes.append(fake)
        if len(fakes) == 2:  # the first reopened link
            return _LostWhenReady(host_end, "socket pair, unplugged again")
        return SocketLink(host_end, "socket pair")

    first, host_end = FakeController.on_socketpair()
    fakes.append(first)
    events: list[ClientEvent] = []
    options = client_options(reconnect=True, boot_timeout_s=2.0, on_event=events.append)

    def reconnected() -> bool:
        return any(isinstance(e, LinkState) and e.state == "reconnected" for e in events)

    expected = "#stop!" if what == "stop" else "#th.90.0!"
    try:
        if client == "blocking":
            rov = Client(SocketLink(host_end, "socket pair"), options, reopen=reopen)
            try:
                rov.start()
                rov.move(90, 50)
                first.close()
                assert wait_until(lambda: _lost(events))
                if what == "stop":
                    rov.stop()
                plugged_back.set()
                assert wait_until(reconnected)
                assert rov.depth_cm() == 123
            finally:
                rov.close()
        else:
            arov = await AsyncClient(
                SocketLink(host_end, "socket pair"), options, reopen=reopen
            ).open()
            try:
                await arov.start()
                await arov.move(90, 50)
                first.close()
                assert await wait_until_async(lambda: _lost(events))
                if what == "stop":
                    await arov.stop()
                plugged_back.set()
                assert await wait_until_async(reconnected)
                assert await arov.depth_cm() == 123
            finally:
                await arov.close()
        assert len(fakes) == 3
        assert fakes[1].frames()[0] == expected
        assert fakes[2].frames()[:3] == [expected, "#crcoff!", "#qd!"]  # again, first
        assert _after_readiness_probe(fakes[2].frames())[:2] == ["#crcoff!", expected]
    finally:
        plugged_back.set()
        for fake in fakes:
            fake.close()


async def test_the_asyncio_clients_raw_frames_wait_for_the_link_as_their_commands_do(
    port: FakeControllerServer,
) -> None:
    """A raw query waits for the reopened link (at most ``timeout``), as ``depth_cm()`` and the
    blocking client's ``send_raw`` do; a raw set frame fails at once, as ``move()`` does. Before,
    a raw query failed at once: the console's ``#qd!`` did, while its ``qd`` waited."""
    events: list[ClientEvent] = []
    async with rovlink.aio.connect(
        port.url, reconnect=True, keepalive=None, timeout=2.0, on_event=events.append
    ) as rov:
        port.refuse = True
        port.fakes[0].close()
        assert await wait_until_async(lambda: _lost(events))
        with pytest.raises(ConnectionLostError, match="lost, reconnecting"):
            await rov.send_raw("#th.0.10!")
        with pytest.raises(ConnectionLostError, match="lost, reconnecting"):
            await rov.move(0, 10)
        queries = [
            asyncio.ensure_future(rov.send_raw("#qd!")),
            asyncio.ensure_future(rov.depth_cm()),
        ]
        await asyncio.sleep(0)
        port.refuse = False
        raw, typed = await asyncio.wait_for(asyncio.gather(*queries), CONDITION_TIMEOUT_S)
        assert (raw, typed) == ((Response("qd", (123,)),), 123)
        assert "#th.0.10!" not in port.fakes[1].frames()
