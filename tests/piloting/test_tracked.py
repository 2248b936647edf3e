"""TrackedClient: every frame it sends is recorded as sent, replies are timed into the health."""

from __future__ import annotations

import pytest

import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import ClientOptions, QueryTimeoutError
from rovlink.client.events import BytesSent
from rovlink.client.links import PortLink, SocketLink
from rovlink.piloting import SentFrame, TrackedClient
from rovlink.protocol import Command
from tests.client.fake_controller import FakeController, FakeControllerServer
from tests.piloting.rig import Rig, SilenceableLink, SilentController, until


async def test_sent_frames_are_reported_as_written_and_update_the_state() -> None:
    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect())
    sent: list[SentFrame] = []
    rov.add_sent_listener(sent.append)
    await rov.send(Command("start"))
    (reply,) = await rov.send(Command("qd"))
    await rov.send(Command("crcon"))
    await rov.send(Command("th", (90, 30)))
    assert [frame.text for frame in sent] == ["#start!", "#qd!", "#crcon!", "#th.90.30F8!"]
    assert rig.frames()[1:] == [frame.text for frame in sent]
    assert reply.name == "qd"
    assert rov.commanded.lock_text() == "unlocked (as last sent)"
    assert rov.health.replies == 1
    assert rov.health.last_reply_s is not None
    await rov.client.close()


async def test_raw_frames_update_the_state_as_the_controller_reads_them() -> None:
    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect(checksum=True))
    sent: list[SentFrame] = []
    rov.add_sent_listener(sent.append)
    await rov.send_raw("#start!")  # no checksum in checksum mode: the controller drops it
    assert sent[-1].command is None
    assert rov.commanded.lock.value == "unknown"
    await rov.send_raw("#start3F!")
    assert sent[-1].command == Command("start")
    assert rov.commanded.lock_text() == "unlocked (as last sent)"
    await rov.send_raw("#stop!")  # honoured in either mode (P3)
    assert sent[-1].command == Command("stop")
    assert rov.commanded.lock_text() == "locked (as last sent)"
    replies = await rov.send_raw("#qd8C!")
    assert [reply.name for reply in replies] == ["qd"]
    assert rig.frames()[-4:] == ["#start!", "#start3F!", "#stop!", "#qd8C!"]
    await rov.client.close()


async def test_a_silent_link_is_counted_as_failures() -> None:
    silent = SilentController()
    client = await AsyncClient(
        silent.link(),
        ClientOptions(timeout_s=0.05, retries=0, keepalive_s=None, boot_timeout_s=None),
    ).open()
    rov = TrackedClient(client)
    with pytest.raises(QueryTimeoutError):
        await rov.sensors()
    assert rov.health.failures == 1
    assert rov.health.status == "no reply"
    await client.close()
    silent.close()


async def test_the_drivers_keep_alives_tell_the_health_whether_the_link_answers() -> None:
    # Before, a tool that queried nothing itself (a console only typed into) showed its link
    # "ok" for ever, from the last reply it had asked for, while the controller had long gone
    # silent and the keep-alives went unanswered.
    port = Rig.simulated().port
    link = SilenceableLink(PortLink(port, "simulated controller"))
    rov = TrackedClient(await Rig(port, link).connect(keepalive_s=0.02, timeout_s=0.05))
    await until(lambda: rov.health.status == "ok")  # the keep-alives are answered
    link.silent.set()
    await until(lambda: rov.health.status == "no reply")
    assert rov.health.failures == 0  # (none of the tool's own queries failed)
    link.silent.clear()
    await until(lambda: rov.health.status == "ok")
    await rov.client.close()


async def test_a_fence_answered_after_the_tools_query_failed_does_not_hide_the_failure() -> None:
    # The driver's fence (a query of another name after a timeout) is answered: the tool's own
    # query failed all the same, and the health says so.
    fake, host_end = FakeController.on_socketpair(script=["drop"])
    options = ClientOptions(timeout_s=0.05, retries=0, keepalive_s=None, boot_timeout_s=None)
    client = await AsyncClient(SocketLink(host_end, "socket pair"), options).open()
    rov = TrackedClient(client)
    with pytest.raises(QueryTimeoutError):
        await rov.send(Command("qd"))
    await until(lambda: fake.queries_answered >= 1)  # the fence
    await until(lambda: client.counters.replies >= 1)
    assert rov.health.consecutive_failures == 1
    assert rov.health.status != "ok"
    await client.close()
    fake.close()


async def test_a_closed_client_sends_and_reports_nothing() -> None:
    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect())
    sent: list[SentFrame] = []
    rov.add_sent_listener(sent.append)
    await rov.client.close()
    for command in (Command("qd"), Command("stop")):
        with pytest.raises(ConnectionError):
            await rov.send(command)
    assert sent == []
    assert rig.frames() == ["#crcoff!"]


async def test_the_sessions_own_zero_thrust_updates_the_state_and_keepalives_do_not_show() -> None:
    from tests.piloting.rig import until

    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect(motion_timeout_s=0.3, keepalive_s=0.05))
    sent: list[SentFrame] = []
    rov.add_sent_listener(sent.append)
    await rov.send(Command("start"))
    await rov.send(Command("th", (90, 40)))
    assert rov.commanded.power_percent == 40
    # The program goes silent: the session expires the motion (P23) and the state follows.
    await until(lambda: rov.commanded.power_percent == 0)
    assert "#th.90.0!" in [frame.text for frame in sent]
    assert rig.frames().count("#qd!") >= 1  # the keep-alives went out …
    assert "#qd!" not in [frame.text for frame in sent]  # … but are not the operator's frames
    await rov.client.close()


async def test_a_command_split_over_raw_writes_leaves_the_lock_unknown() -> None:
    # "raw #sta" then "raw rt!" is #start! to the controller: the lock is not known any more.
    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect())
    await rov.send(Command("stop"))
    assert rov.commanded.lock_text() == "locked (as last sent)"
    await rov.send_raw("#sta")
    await rov.send_raw("rt!")
    assert rov.commanded.lock.value == "unknown"
    assert rov.commanded.lock_text() == "unknown: after a raw write whose effect is not known"
    await rov.send(Command("stop"))
    assert rov.commanded.lock_text() == "locked (as last sent)"
    await rov.client.close()


async def test_the_drivers_own_frames_are_not_last_sent() -> None:
    # The session re-asserts #crcoff! after timeouts (P21): the pilot's #th.0.10! stays last.
    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect())
    sent: list[SentFrame] = []
    rov.add_sent_listener(sent.append)
    await rov.send(Command("start"))
    await rov.send(Command("th", (0, 10)))
    rov._on_event(BytesSent(0.0, b"#crcoff!", Command("crcoff"), by_session=True))
    rov._on_event(BytesSent(0.0, b"#th.0.0!", Command("th", (0, 0)), by_session=True))
    assert str(rov.commanded.last_command) == "#th.0.10!"
    assert rov.commanded.power_percent == 0  # (what the driver's zero thrust did, all the same)
    assert [frame.text for frame in sent][-2:] == ["#crcoff!", "#th.0.0!"]  # (shown as sent)
    await rov.client.close()


async def test_a_suspected_controller_reset_makes_the_state_as_last_sent_unknown() -> None:
    # Before, after the driver had said "controller reset suspected ... the robot is locked
    # after a reset", the tools still showed "unlocked (as last sent)" at 30 %, and took a
    # th sent next for one the controller acts on (P21: a host never assumes it still is).
    rig = Rig.simulated()
    rov = TrackedClient(await rig.connect(checksum=True, timeout_s=0.25, retries=2))
    for command in (Command("start"), Command("mvdirect", (1,)), Command("th", (90, 30))):
        await rov.send(command)
    rig.port.controller.reset()  # checksum off: it drops the #qd8C! until the mode is re-sent
    (reply,) = await rov.send(Command("qd"))
    assert reply.name == "qd"  # (answered once the driver re-asserted checksum mode)
    state = rov.commanded
    assert state.lock_text() == "unknown: after a suspected controller reset (locked after one)"
    assert state.mode_text() == "unknown: after a suspected controller reset (depth mode after one)"
    assert (state.short_lock_text(), state.short_mode_text()) == ("lock unknown", "mode unknown")
    assert state.horizontal_text() == "0° at 0 % (as last sent)"
    await rov.send(Command("start"))
    assert state.lock_text() == "unlocked (as last sent)"
    await rov.client.close()


@pytest.mark.integration
async def test_a_reopened_link_forgets_the_lock_and_puts_the_motion_at_rest() -> None:
    port = FakeControllerServer()
    async with rovlink.aio.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as client:
        rov = TrackedClient(client)
        await rov.send(Command("start"))
        await rov.send(Command("th", (270, 40)))
        port.fakes[0].close()  # unplugged and plugged back
        await until(lambda: len(port.fakes) == 2)
        await rov.send(Command("qd"))  # (waits for the reconnection)
        assert not rov.link_down
        state = rov.commanded
        assert state.lock_text() == (
            "unknown: after the link was reopened (the controller may have reset)"
        )
        assert state.horizontal_text() == "270° at 0 % (as last sent)"  # the driver zeroed it
        assert port.fakes[1].frames()[0] == "#th.270.0!"
        # Before, the last sent stayed #th.270.40!, sent on the old link, which the driver's
        # zero thrust had undone on the new one.
        assert (state.last_command, state.last_forgotten_on_reopening) == (None, True)
        await rov.send(Command("start"))
        assert (state.last_command, state.last_forgotten_on_reopening) == (Command("start"), False)
    port.close()


@pytest.mark.integration
async def test_a_stop_while_the_link_is_down_leaves_it_locked_once_reopened() -> None:
    port = FakeControllerServer()
    async with rovlink.aio.connect(port.url, reconnect=True, keepalive=None, timeout=2.0) as client:
        rov = TrackedClient(client)
        await rov.send(Command("start"))
        port.refuse = True  # unplugged
        port.fakes[0].close()
        await until(lambda: rov.link_down)
        await rov.stop()  # kept: the reopened link's first frame
        port.refuse = False
        await until(lambda: len(port.fakes) == 2)
        await rov.send(Command("qd"))
        assert rov.commanded.lock_text() == "locked (as last sent)"
        assert port.fakes[1].frames()[0] == "#stop!"
        assert rov.commanded.last_command == Command("stop")  # (it went on the reopened link)
    port.close()
