"""A recording tells the driver's retries from the program's queries, so that a replay sends
each query of the program once, and every one of them."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

import rovlink
import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import Client, ClientOptions, QueryTimeoutError
from rovlink.client.links import SocketLink
from rovlink.protocol import Command, Response
from rovlink.recorder import FrameEntry, Recorder, read_entries
from rovlink.recorder.comparison import replay_steps
from tests.client.fake_controller import FakeController

#: Short: the dropped attempts time out, the answered ones come at once.
_TIMEOUT_S = 0.15


def _options(recorder: Recorder, **overrides: object) -> ClientOptions:
    settings: dict[str, object] = {
        "timeout_s": _TIMEOUT_S,
        "keepalive_s": None,
        "boot_timeout_s": None,
        "motion_timeout_s": None,
        "on_event": recorder.on_event,
    }
    settings.update(overrides)
    return ClientOptions(**settings)  # type: ignore[arg-type]


def _steps(path: Path) -> list[tuple[Command, list[Response] | None, int]]:
    return [
        (step.command, step.recorded, step.expected_count)
        for step in replay_steps(read_entries(str(path)))
    ]


_QD = Command("qd")
_ANSWER = [Response("qd", (123,))]


def test_concurrent_queries_retried_are_replayed_once_each(tmp_path: Path) -> None:
    # Two queries on the wire at once both time out and are retried: the second failure was
    # taken for final (a qd came between it and its retry), its retry for a query of the
    # program's, and a replay sent three queries where the program had asked two.
    path = tmp_path / "dive.jsonl"
    fake, sock = FakeController.on_socketpair(script=("drop", "drop"))

    async def drive() -> None:
        with Recorder(str(path)) as recorder:
            client = AsyncClient(SocketLink(sock, "pair"), _options(recorder), max_in_flight=2)
            async with await client.open() as rov:
                assert list(await asyncio.gather(rov.depth_cm(), rov.depth_cm())) == [123, 123]

    try:
        asyncio.run(drive())
    finally:
        fake.close()
    assert fake.frames().count("#qd!") == 4
    assert _steps(path) == [(_QD, _ANSWER, 1), (_QD, _ANSWER, 1)]
    retries = [
        entry.retry
        for entry in read_entries(str(path))
        if isinstance(entry, FrameEntry) and entry.name == "qd" and entry.direction == "out"
    ]
    assert retries == [False, False, True, True]


def test_a_program_asking_again_after_a_final_failure_is_replayed_both_times(
    tmp_path: Path,
) -> None:
    # Without retries the failure is final and the program asks again itself: that query was
    # taken for the driver's retry, and a replay left it out.
    path = tmp_path / "dive.jsonl"
    fake, sock = FakeController.on_socketpair(script=("drop",))
    try:
        with (
            Recorder(str(path)) as recorder,
            Client(SocketLink(sock, "pair"), _options(recorder, retries=0)) as rov,
        ):
            with pytest.raises(QueryTimeoutError):
                rov.depth_cm()
            assert rov.depth_cm() == 123
    finally:
        fake.close()
    assert _steps(path) == [(_QD, None, 1), (_QD, _ANSWER, 1)]


@pytest.mark.parametrize("kind", ["blocking", "asyncio"])
def test_the_drivers_checksum_confirmation_is_its_own(tmp_path: Path, kind: str) -> None:
    # With checksums on, the driver confirms the mode with a #qd! of its own as it connects: it
    # was recorded as the program's, listed without "(by the driver)", and a replay sent it
    # as one of the program's queries (besides the replaying driver's own).
    path = tmp_path / "dive.jsonl"
    with Recorder(str(path), url="sim://?seed=1") as recorder:
        if kind == "blocking":
            with rovlink.connect("sim://?seed=1", checksum=True, on_event=recorder.on_event) as rov:
                rov.depth_cm()
        else:

            async def drive() -> None:
                url = "sim://?seed=1"
                async with rovlink.aio.connect(
                    url, checksum=True, on_event=recorder.on_event
                ) as rov:
                    await rov.depth_cm()

            asyncio.run(drive())
    queries = [
        entry.by_session
        for entry in read_entries(str(path))
        if isinstance(entry, FrameEntry) and entry.name == "qd" and entry.direction == "out"
    ]
    assert queries == [True, False]  # (the connect probe's #qd! is on the wire alone)
    assert [command for command, _, _ in _steps(path)] == [_QD]
