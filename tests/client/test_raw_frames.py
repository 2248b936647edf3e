"""``send_raw``: a frame exactly as given, its motion and its replies tracked like any other."""

from __future__ import annotations

import pytest

from rovlink.client import parse_command_text
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.client.operations import any_command
from rovlink.client.session import Session
from rovlink.protocol import Command, Response
from tests.client.conftest import wait_until_async
from tests.client.fake_controller import FakeController
from tests.client.test_aio import MakeAsyncClient
from tests.client.test_blocking import MakeClient

#: Two command frames in one raw chunk: before, neither was tracked (a motion that never
#: expired, P23) and the replies of queries among them were counted as stray.
TWO_FRAMES = [b"#start!#th.90.60!", b"#qd!#qr!", b"#qd!#th.90.60!"]


@pytest.mark.parametrize("chunk", TWO_FRAMES)
def test_the_blocking_client_sends_one_raw_frame_at_a_time(
    fake: FakeController, make_client: MakeClient, chunk: bytes
) -> None:
    client = make_client()
    with pytest.raises(ValueError, match=r"holds 2 commands .*; send each on its own"):
        client.send_raw(chunk)
    assert client.send_raw("#qd!") == client.send(Command("qd"))  # nothing of it was sent
    assert fake.wait_for(lambda f: len(f.commands) == 3)
    assert fake.frames()[1:] == ["#qd!", "#qd!"]


@pytest.mark.parametrize("chunk", TWO_FRAMES)
async def test_the_asyncio_client_sends_one_raw_frame_at_a_time(
    fake: FakeController, make_async_client: MakeAsyncClient, chunk: bytes
) -> None:
    client = await make_async_client()
    with pytest.raises(ValueError, match=r"holds 2 commands .*; send each on its own"):
        await client.send_raw(chunk)
    assert await client.send_raw("#qd!") == await client.send(Command("qd"))
    assert fake.frames()[1:] == ["#qd!", "#qd!"]


#: What a program may pass by mistake, and the type error each is (before: an AttributeError
#: of the str, "'str' object has no attribute 'setting'", and a ValueError for a frame's type).
WRONG_TYPES = [
    (
        "send",
        "qd",
        r"send: command must be a rovlink\.protocol\.Command, got 'qd' \(text as "
        r"typed: send\(parse_command_text\('qd'\)\)\)$",
    ),
    ("send", b"#qd!", r"send: command must be a rovlink\.protocol\.Command, got b'#qd!'"),
    ("send", Response("qd", (1,)), r"send: command must be a rovlink\.protocol\.Command"),
    ("send_raw", 123, r"send_raw: frame must be text or bytes, got 123"),
]


#: What ``send`` names for text or bytes: a way in that works for that argument. (Before, every
#: one named both: ``send_raw('qd')`` sends two letters that are no frame, which the controller
#: ignores, and ``parse_command_text(b'#qd!')`` failed with a TypeError of ``str.startswith``.)
SEND_HINTS = [
    ("qd", "(text as typed: send(parse_command_text('qd')))"),
    ("th 90 40", "(text as typed: send(parse_command_text('th 90 40')))"),
    ("#qd!", "(a frame: send(parse_command_text('#qd!')), or exactly as it is: send_raw('#qd!'))"),
    (b"#qd!", "(a frame exactly as it is: send_raw(b'#qd!'))"),
]


@pytest.mark.parametrize(("argument", "hint"), SEND_HINTS)
def test_send_names_a_way_in_that_works_for_its_argument(argument: str | bytes, hint: str) -> None:
    with pytest.raises(TypeError) as raised:
        any_command(argument)  # type: ignore[arg-type]
    assert str(raised.value) == (
        f"send: command must be a rovlink.protocol.Command, got {argument!r} {hint}"
    )


def test_the_way_in_named_for_a_frame_works() -> None:
    assert parse_command_text("#qd!") == Command("qd")
    with pytest.raises(TypeError, match=r"^parse_command_text: text must be a str, got b'#qd!'$"):
        parse_command_text(b"#qd!")  # type: ignore[arg-type]


@pytest.mark.parametrize(("method", "argument", "message"), WRONG_TYPES)
def test_the_blocking_client_says_what_send_takes(
    fake: FakeController, make_client: MakeClient, method: str, argument: object, message: str
) -> None:
    client = make_client()
    with pytest.raises(TypeError, match=message):
        getattr(client, method)(argument)
    assert client.send(Command("qd"))  # nothing of it was sent
    assert fake.frames()[1:] == ["#qd!"]


@pytest.mark.parametrize(("method", "argument", "message"), WRONG_TYPES)
async def test_the_asyncio_client_says_what_send_takes(
    fake: FakeController,
    make_async_client: MakeAsyncClient,
    method: str,
    argument: object,
    message: str,
) -> None:
    client = await make_async_client()
    with pytest.raises(TypeError, match=message):
        await getattr(client, method)(argument)
    assert await client.send(Command("qd"))
    assert fake.frames()[1:] == ["#qd!"]


def test_a_raw_motion_frame_among_noise_still_expires() -> None:
    session = Session(motion_timeout_s=1.0)
    data, pending = session.raw(b"\r\nxx#th.90.60!", now=0.0)
    assert (data, pending) == (b"\r\nxx#th.90.60!", None)
    session.tick(now=1.0)
    assert session.take_outbox(now=1.0) == b"#th.90.0!"


def test_a_raw_set_command_is_reported_at_once(
    fake: FakeController, make_client: MakeClient
) -> None:
    # (Before, its BytesSent waited for the background reader or the next call.)
    client = make_client()
    events: list[ClientEvent] = []
    client.subscribe(events.append)
    client.send_raw(b"#mgmp.5!")
    assert [event.data for event in events if isinstance(event, BytesSent)] == [b"#mgmp.5!"]


async def test_the_asyncio_client_reports_a_raw_set_command_too(
    fake: FakeController, make_async_client: MakeAsyncClient
) -> None:
    client = await make_async_client()
    events: list[ClientEvent] = []
    client.subscribe(events.append)
    await client.send_raw(b"#mgmp.5!")
    assert [event.data for event in events if isinstance(event, BytesSent)] == [b"#mgmp.5!"]
    assert await wait_until_async(lambda: "#mgmp.5!" in fake.frames())
