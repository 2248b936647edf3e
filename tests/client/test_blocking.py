"""The blocking client against a scripted fake controller on a socket pair."""

from __future__ import annotations

import logging
import random
import threading
from collections.abc import Callable
from typing import Any

import pytest

from rovlink.client import (
    Client,
    ConnectionLostError,
    InvalidArgumentError,
    QueryTimeoutError,
)
from rovlink.protocol import Command, Event, Frame, Response, Text, get_algorithm
from tests.client.conftest import NO_REPLY_TIMEOUT_S, REPLY_TIMEOUT_S, wait_until
from tests.client.fake_controller import FakeController
from tests.client.method_cases import CHECKSUM_CASES, QUERY_CASES, SET_CASES, checksummed

MakeClient = Callable[..., Client]


def _sent_after_connect(fake: FakeController, count: int) -> bytes:
    """The bytes after the connect frame, once ``count`` more frames arrived."""
    assert fake.wait_for(lambda f: len(f.commands) >= 1 + count)
    raw = bytes(fake.raw)
    for connect_frame in (b"#crcon!", b"#crcoff!"):
        if raw.startswith(connect_frame):
            return raw[len(connect_frame) :]
    raise AssertionError(f"no checksum mode frame first: {raw!r}")


@pytest.mark.parametrize("checksum", [False, True])
def test_connect_puts_the_controller_in_the_asked_mode(
    fake: FakeController, make_client: MakeClient, checksum: bool
) -> None:
    client = make_client(checksum=checksum)
    assert fake.wait_for(lambda f: len(f.commands) == 1)
    assert bytes(fake.raw) == (b"#crcon!" if checksum else b"#crcoff!")
    assert fake.decoder.checksum_enabled is checksum
    assert client.checksum_enabled is checksum


@pytest.mark.parametrize(("method", "args", "kwargs", "frames"), SET_CASES)
def test_set_commands_send_exact_frames(
    fake: FakeController,
    make_client: MakeClient,
    method: str,
    args: tuple[Any, ...],
    kwargs: dict[str, Any],
    frames: list[bytes],
) -> None:
    client = make_client()
    assert getattr(client, method)(*args, **kwargs) is None
    assert _sent_after_connect(fake, len(frames)) == b"".join(frames)


@pytest.mark.parametrize(("method", "args", "kwargs", "frames"), SET_CASES)
def test_set_commands_carry_checksums_in_checksum_mode(
    fake: FakeController,
    make_client: MakeClient,
    method: str,
    args: tuple[Any, ...],
    kwargs: dict[str, Any],
    frames: list[bytes],
) -> None:
    client = make_client(checksum=True)
    getattr(client, method)(*args, **kwargs)
    expected = b"".join(checksummed(f) for f in frames)
    assert _sent_after_connect(fake, len(frames)) == expected
    assert fake.bad_frames == []  # the fake controller accepted every checksum


@pytest.mark.parametrize(("method", "frame", "expected"), QUERY_CASES)
@pytest.mark.parametrize("checksum", [False, True])
def test_queries_send_exact_frames_and_decode_replies(
    fake: FakeController,
    make_client: MakeClient,
    method: str,
    frame: bytes,
    expected: Any,
    checksum: bool,
) -> None:
    client = make_client(checksum=checksum)
    assert getattr(client, method)() == expected
    sent = _sent_after_connect(fake, 1)
    if checksum:
        assert sent == frame[:-1] + get_algorithm("crc8").digits(frame[1:-1]) + b"!"
    else:
        assert sent == frame
    assert client.counters.replies == 1


@pytest.mark.parametrize(("method", "args", "frame"), CHECKSUM_CASES)
def test_protocol_part_3_vectors(
    fake: FakeController, make_client: MakeClient, method: str, args: tuple[Any, ...], frame: bytes
) -> None:
    client = make_client(checksum=True)
    getattr(client, method)(*args)
    assert _sent_after_connect(fake, 1) == frame


@pytest.mark.parametrize("algorithm", ["xor", "sum8"])
def test_other_checksum_algorithms(algorithm: str) -> None:
    fake, sock = FakeController.on_socketpair(algorithm=algorithm)
    from rovlink.client import ClientOptions
    from rovlink.client.links import SocketLink

    options = ClientOptions(
        checksum=True, algorithm=algorithm, keepalive_s=None, timeout_s=REPLY_TIMEOUT_S
    )
    with Client(SocketLink(sock, "pair"), options) as client:
        assert client.heading_deg() == 275
        expected = b"#qhe" + get_algorithm(algorithm).digits(b"qhe") + b"!"
        assert bytes(fake.raw).endswith(expected)
    fake.close()


def test_invalid_arguments_send_nothing(fake: FakeController, make_client: MakeClient) -> None:
    client = make_client()
    with pytest.raises(InvalidArgumentError, match="power_percent must be in 0–100"):
        client.move(90, 150)
    with pytest.raises(InvalidArgumentError, match="d must be in 0–99"):
        client.set_depth_pid(p=10, i=5, d=100)  # p and i are valid, yet not sent
    with pytest.raises(TypeError):
        client.set_debug("on")  # type: ignore[arg-type]
    client.stop()  # a marker: everything before it would have arrived first
    assert _sent_after_connect(fake, 1) == b"#stop!"
    assert client.counters.frames_sent == 2


def test_set_checksum_switches_the_client_and_the_controller(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client()
    client.set_checksum(True)
    assert client.checksum_enabled
    assert client.depth_cm() == 123
    assert bytes(fake.raw).endswith(b"#crcon!#qd8C!")
    client.set_checksum(False)
    assert client.depth_cm() == 123
    assert bytes(fake.raw).endswith(b"#crcoff!#qd!")
    assert fake.bad_frames == []


def test_a_query_with_no_reply_times_out_naming_the_query(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client(retries=2, timeout_s=NO_REPLY_TIMEOUT_S)
    fake.then(*["drop"] * 10)  # a silent controller: the fences (P20) go unanswered too
    with pytest.raises(QueryTimeoutError) as caught:
        client.heading_deg()
    error = caught.value
    assert isinstance(error, TimeoutError)
    assert error.query == Command("qhe")
    assert error.failures == ("timeout", "timeout", "timeout")
    assert "#qhe!" in str(error)
    counters = client.counters
    assert counters.retries == 2
    # The unanswered fences (P20) time out too.
    assert counters.timeouts >= 3
    assert counters.fences >= 1
    assert fake.frames().count("#qhe!") == 3


def test_retries_zero_means_one_attempt(fake: FakeController, make_client: MakeClient) -> None:
    client = make_client(retries=0, timeout_s=NO_REPLY_TIMEOUT_S)
    fake.then("drop")
    # It says where: which of a program's links did not answer (before, it did not say).
    with pytest.raises(QueryTimeoutError, match=r"\(1 attempt: timeout\) on socket pair$"):
        client.depth_cm()
    assert fake.frames().count("#qd!") == 1


@pytest.mark.parametrize("action", ["drop", "corrupt"])
@pytest.mark.parametrize("checksum", [False, True])
def test_a_lost_or_corrupt_reply_is_retried(
    fake: FakeController, make_client: MakeClient, action: str, checksum: bool
) -> None:
    client = make_client(checksum=checksum, drops_time_out_at_once=True)
    fake.then(action)
    assert client.sensors().heading_deg == 275
    counters = client.counters
    assert counters.retries == 1
    assert counters.checksum_errors == (1 if action == "corrupt" and checksum else 0)
    assert counters.bad_frames == (1 if action == "corrupt" else 0)
    assert fake.frames().count("#qsa!") == 2


def test_set_commands_are_never_repeated(fake: FakeController, make_client: MakeClient) -> None:
    client = make_client(drops_time_out_at_once=True)
    fake.then("drop")
    client.move(0, 40)
    assert client.depth_cm() == 123  # retried once
    # The retry goes after a fence (P20): a query of another name, whose reply ends the wait
    # for a late reply to the first attempt.
    assert fake.frames()[1:] == ["#th.0.40!", "#qd!", "#qhe!", "#qd!"]


@pytest.mark.parametrize("action", ["debug", "noise"])
def test_debug_text_and_noise_are_skipped_and_reported(
    fake: FakeController,
    make_client: MakeClient,
    action: str,
    caplog: pytest.LogCaptureFixture,
) -> None:
    seen: list[Event] = []
    client = make_client(on_stray=seen.append)
    fake.then(action)
    with caplog.at_level(logging.INFO, logger="rovlink.client"):
        assert client.sensors().depth_cm == 123
        # The reader counts and logs a line before it hands the line to the callback.
        assert wait_until(lambda: bool(seen) and client.counters.text_lines == len(seen))
    assert all(isinstance(event, Text) for event in seen)
    assert client.counters.retries == 0
    assert any("controller:" in record.getMessage() for record in caplog.records)


def test_stray_frames_go_to_the_callback(fake: FakeController, make_client: MakeClient) -> None:
    seen: list[Event] = []
    client = make_client(on_stray=seen.append)
    fake.send(b"$qhe.10!")
    assert wait_until(lambda: bool(seen))
    assert isinstance(seen[0], Frame)
    assert seen[0].message == Response("qhe", (10,))
    assert client.counters.stray_frames == 1
    assert client.depth_cm() == 123  # the stray frame did not answer this query


def test_a_failing_callback_does_not_stop_the_reader(
    fake: FakeController, make_client: MakeClient
) -> None:
    def explode(event: Event) -> None:
        raise RuntimeError("callback bug")

    client = make_client(on_stray=explode)
    fake.then("debug")
    assert client.depth_cm() == 123
    assert client.depth_cm() == 123


def test_a_callback_may_use_the_client(fake: FakeController, make_client: MakeClient) -> None:
    depths: list[int] = []
    client: Client | None = None

    def on_stray(event: Event) -> None:
        if isinstance(event, Text) and client is not None:
            depths.append(client.depth_cm())  # runs after the reader role is given up

    client = make_client(on_stray=on_stray)
    fake.send(b"debug: unsolicited line\r\n")  # read by the background reader
    assert wait_until(lambda: len(depths) == 1)
    fake.then("debug")  # read by the caller waiting for its own reply
    assert client.heading_deg() == 275
    assert wait_until(lambda: len(depths) == 3)
    assert depths == [123, 123, 123]


def test_disconnect_fails_the_pending_query_and_every_later_call(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client()
    fake.then("close")
    with pytest.raises(ConnectionLostError, match="closed by the other end"):
        client.depth_cm()
    assert client.closed
    with pytest.raises(ConnectionLostError):
        client.stop()
    with pytest.raises(ConnectionError):  # the built-in base works too
        client.sensors()


def test_disconnect_while_idle_is_noticed(fake: FakeController, make_client: MakeClient) -> None:
    client = make_client()
    fake.close()
    assert wait_until(lambda: client.closed)
    with pytest.raises(ConnectionLostError):
        client.move(0, 10)


def test_close_fails_waiting_queries(fake: FakeController, make_client: MakeClient) -> None:
    # close() gives the query on the wire its timeout to be answered; it is not, and the
    # caller's retry finds the client closed. Every attempt is dropped, and there are enough of
    # them for the caller to be still trying however late close() comes.
    client = make_client(timeout_s=NO_REPLY_TIMEOUT_S, retries=10)
    fake.then(*["drop"] * 11)
    errors: list[BaseException] = []

    def ask() -> None:
        try:
            client.depth_cm()
        except BaseException as error:
            errors.append(error)

    thread = threading.Thread(target=ask)
    thread.start()
    assert fake.wait_for(lambda f: "#qd!" in f.frames())
    client.close()
    thread.join(5.0)
    assert not thread.is_alive()
    assert len(errors) == 1
    assert isinstance(errors[0], ConnectionLostError)
    client.close()  # idempotent


def test_leaving_the_with_block_by_an_error_stops_the_robot(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client()

    def failing_program() -> None:
        with client:
            client.move(0, 50)
            raise KeyError("the robot program failed")

    with pytest.raises(KeyError):
        failing_program()
    assert fake.wait_for(lambda f: f.frames()[-1:] == ["#stop!"])
    assert client.closed


def test_keepalive_queries_keep_an_idle_link_busy(
    fake: FakeController, make_client: MakeClient
) -> None:
    client = make_client(keepalive_s=0.02)
    assert fake.wait_for(lambda f: f.frames().count("#qd!") >= 3)
    assert client.counters.keepalives >= 3
    assert wait_until(lambda: client.counters.replies >= 3)
    assert client.counters.timeouts == 0


def test_send_any_command_and_raw_frames(fake: FakeController, make_client: MakeClient) -> None:
    client = make_client()
    assert client.send(Command("qhe")) == (Response("qhe", (275,)),)
    assert client.send(Command("th", (90, 40))) == ()
    assert client.send_raw("#qd!") == (Response("qd", (123,)),)
    assert client.send_raw(b"#bogus.1!") == ()
    assert client.send_raw("#crcon!") == ()
    assert client.checksum_enabled
    assert client.send_raw("#qd8C!") == (Response("qd", (123,)),)
    assert _sent_after_connect(fake, 5) == (  # #bogus.1! is no command: the fake drops it
        b"#qhe!#th.90.40!#qd!#bogus.1!#crcon!#qd8C!"
    )


def test_many_threads_get_their_own_replies(
    fake: FakeController,
    make_client: MakeClient,
) -> None:
    client = make_client()
    queries = [
        ("depth_cm", 123),
        ("heading_deg", 275),
        ("roll_deg", -1),
        ("pitch_deg", 15),
        ("pressure_raw", 530),
    ]
    wrong: list[str] = []

    def worker(seed: int) -> None:
        rng = random.Random(seed)
        for _ in range(40):
            method, expected = rng.choice(queries)
            result = getattr(client, method)()
            if result != expected:
                wrong.append(f"{method} → {result}")
            if rng.random() < 0.2:
                client.move(rng.randrange(361), rng.randrange(101))

    threads = [threading.Thread(target=worker, args=(seed,)) for seed in range(6)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(20.0)
    assert wrong == []
    assert client.counters.replies == 240
    assert fake.bad_frames == []


def test_replies_keep_their_order_under_concurrency(
    fake: FakeController, make_client: MakeClient
) -> None:
    fake.qd_counts_queries = True
    client = make_client()
    results: list[int] = []
    lock = threading.Lock()

    def worker() -> None:
        for _ in range(50):
            value = client.depth_cm()
            with lock:
                results.append(value)

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(20.0)
    assert sorted(results) == list(range(1, 201))  # every reply went to exactly one caller
