"""P23: a motion command the program does not renew expires with zero thrust.

The keep-alive feeds the controller's link-loss failsafe (P17) even when the program that
commanded thrust has hung; the host's motion timeout is what stops the robot then.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Callable

import pytest

from rovlink.client.errors import ConnectionLostError, QueryTimeoutError
from rovlink.client.events import MotionExpired
from rovlink.client.session import Session
from rovlink.protocol import Command
from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until, wait_until_async
from tests.client.fake_controller import FakeController
from tests.client.test_aio import MakeAsyncClient
from tests.client.test_blocking import MakeClient


def test_unrenewed_motion_expires_with_zero_thrust_in_the_session() -> None:
    session = Session(motion_timeout_s=1.0, record_events=True)
    session.command(Command("start"), now=0.0)
    session.command(Command("mvdirect", (1,)), now=0.0)
    session.command(Command("th", (90, 40)), now=0.0)
    session.command(Command("mvs", (-30,)), now=0.5)  # renews the motion as a whole
    assert session.next_deadline() == pytest.approx(1.5)
    session.tick(now=1.4)
    assert session.take_outbox(now=1.4) == b""
    session.tick(now=1.5)
    assert session.take_outbox(now=1.5) == b"#th.90.0!#mvs.+0!"
    assert session.counters.motion_expiries == 1
    expired = [event for event in session.take_events() if isinstance(event, MotionExpired)]
    assert [str(command) for command in expired[0].commands] == ["#th.90.0!", "#mvs.+0!"]
    session.tick(now=5.0)  # nothing moves any more: nothing more to expire
    assert session.take_outbox(now=5.0) == b""


def test_a_closing_driver_is_given_only_the_zero_thrust_of_what_is_due() -> None:
    session = Session(motion_timeout_s=1.0, timeout_s=0.5, keepalive_s=0.2)
    session.command(Command("th", (90, 40)), now=0.0)
    session.query(Command("qd"), now=0.0)
    session.tick(now=1.0)  # the query timed out (a fence due), the motion expired, keep-alive
    assert session.take_outbox_when_closing(now=1.0) == b"#th.90.0!"
    assert not session.has_outbox
    assert session.counters.motion_expiries == 1


def test_renewed_zero_or_stopped_motion_never_expires() -> None:
    session = Session(motion_timeout_s=1.0)
    session.command(Command("th", (0, 50)), now=0.0)
    for step in range(1, 10):  # renewed every 0.5 s
        session.command(Command("th", (0, 50)), now=step * 0.5)
        session.tick(now=step * 0.5 + 0.4)
        assert session.take_outbox(now=step * 0.5 + 0.4) == b""
    session.command(Command("th", (0, 0)), now=5.0)  # zero power: nothing to expire
    session.tick(now=10.0)
    session.command(Command("th", (0, 50)), now=10.0)
    session.command(Command("stop"), now=10.1)  # stop clears the set-points (P7)
    session.tick(now=20.0)
    assert session.take_outbox(now=20.0) == b""
    assert session.counters.motion_expiries == 0


def test_a_silent_program_stops_the_robot_through_the_blocking_client(
    fake: FakeController,
    make_client: MakeClient,
    caplog: pytest.LogCaptureFixture,
) -> None:
    client = make_client(motion_timeout_s=0.3, keepalive_s=0.1)
    client.start()
    client.move(45, 60)
    # The program goes silent; the keep-alive goes on, but the motion is expired.
    assert fake.wait_for(lambda f: "#th.45.0!" in f.frames())
    assert wait_until(lambda: client.counters.motion_expiries == 1)
    assert fake.frames().count("#th.45.0!") == 1
    assert wait_until(
        lambda: any(
            record.levelno == logging.WARNING and "#th.45.0!" in record.getMessage()
            for record in caplog.records
        )
    )


async def test_a_silent_program_stops_the_robot_through_the_asyncio_client(
    fake: FakeController,
    make_async_client: MakeAsyncClient,
) -> None:
    client = await make_async_client(motion_timeout_s=0.3)
    await client.start()
    await client.set_direct_mode(True)
    await client.set_vertical_thrust(-40)
    assert await wait_until_async(lambda: "#mvs.+0!" in fake.frames())
    assert client.counters.motion_expiries == 1


def test_motion_that_expires_while_the_blocking_client_closes_is_still_zeroed(
    fake: FakeController, make_client: MakeClient
) -> None:
    """close() waits (up to the timeout) for a query on the wire; a motion that expires in that
    wait is zeroed all the same, as it would be without the close (before, nothing was written
    while closing, and only the controller's own failsafe stopped the robot, 2 s after)."""
    # (No #stop! on close, which would zero the motion before it expires.)
    client = make_client(motion_timeout_s=0.5, timeout_s=1.0, stop_on_close=False)
    client.start()
    client.move(45, 60)
    fake.then("drop")
    asker = threading.Thread(target=_ignore_timeout(client.depth_cm), daemon=True)
    asker.start()
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    assert client.counters.motion_expiries == 0
    closer = threading.Thread(target=client.close, daemon=True)
    closer.start()
    assert fake.wait_for(lambda f: "#th.45.0!" in f.frames())
    closer.join(CONDITION_TIMEOUT_S)
    asker.join(CONDITION_TIMEOUT_S)
    assert fake.frames().count("#th.45.0!") == 1


async def test_motion_that_expires_while_the_asyncio_client_closes_is_still_zeroed(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client(motion_timeout_s=0.5, timeout_s=1.0, stop_on_close=False)
    await client.start()
    await client.move(45, 60)
    fake.then("drop")
    asker = asyncio.ensure_future(client.depth_cm())
    assert await asyncio.to_thread(fake.wait_for, lambda f: "#qd!" in f.frames())
    assert client.counters.motion_expiries == 0
    await client.close()  # waits for the dropped query's timeout
    assert "#th.45.0!" in fake.frames()
    with pytest.raises((QueryTimeoutError, ConnectionLostError)):
        await asyncio.wait_for(asker, CONDITION_TIMEOUT_S)


def _ignore_timeout(query: Callable[[], object]) -> Callable[[], None]:
    def run() -> None:
        with contextlib.suppress(QueryTimeoutError, ConnectionLostError):
            query()

    return run


@pytest.mark.parametrize(
    "kept_by",
    [
        [Command("start")],  # already unlocked: nothing changes (P7)
        [Command("mvdirect", (1,))],  # the mode it is in: nothing changes (P9)
        [Command("mvdirect", (0,))],  # a change: vertical thrust 0, horizontal kept (P9, P11)
    ],
    ids=["start-again", "same-mode", "mode-change"],
)
def test_thrust_the_controller_keeps_across_a_command_still_expires(
    kept_by: list[Command],
) -> None:
    session = Session(motion_timeout_s=1.0)
    session.command(Command("start"), now=0.0)
    session.command(Command("mvdirect", (1,)), now=0.0)
    session.command(Command("th", (90, 40)), now=0.0)
    session.command(Command("mvs", (30,)), now=0.0)
    for command in kept_by:
        session.command(command, now=0.5)
    session.tick(now=1.0)
    expired = session.take_outbox(now=1.0)
    assert expired.startswith(b"#th.90.0!")
    changes_mode = kept_by == [Command("mvdirect", (0,))]
    assert (b"#mvs.+0!" in expired) is not changes_mode
