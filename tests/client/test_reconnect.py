"""reconnect=True: a lost link (an adapter unplugged and plugged back) is reopened and reused."""

from __future__ import annotations

import pytest

import rovlink
import rovlink.aio
from rovlink.client.errors import ConnectionLostError
from rovlink.client.events import ClientEvent, LinkState
from tests.client.conftest import wait_until, wait_until_async
from tests.client.fake_controller import FakeControllerServer

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
    assert frames[:2] == ["#crcoff!", "#qd!"]
    return frames[2:]


def test_motion_is_zeroed_first_on_a_reopened_link(port: FakeControllerServer) -> None:
    # Only the link dropped: the controller may still drive the last thrust, and the queries
    # that follow would feed its watchdog (P17). Zero thrust goes first on the new link.
    with rovlink.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as rov:
        rov.start()
        rov.move(90, 50)
        rov.set_vertical_thrust(-30)
        port.fakes[0].close()
        assert wait_until(lambda: len(port.fakes) == 2)
        assert rov.depth_cm() == 123
        after_probe = _after_readiness_probe(port.fakes[1].frames())
        assert after_probe[:2] == ["#th.90.0!", "#mvs.+0!"]


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
        assert _after_readiness_probe(port.fakes[1].frames())[0] == "#th.270.0!"
