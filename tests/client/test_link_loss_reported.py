"""A link lost while the program is idle (the keep-alive's, or the background reader's) is
reported at once in a warning naming the port and why, by both clients, and the client is
closed: its next call raises ConnectionLostError with the same reason. Before, the blocking
client said nothing until the program's next call."""

from __future__ import annotations

import logging

import pytest

from rovlink.client import ConnectionLostError
from tests.client.conftest import wait_until, wait_until_async
from tests.client.fake_controller import FakeController
from tests.client.test_aio import MakeAsyncClient
from tests.client.test_blocking import MakeClient

_REASON = "socket pair: closed by the other end"


def test_the_blocking_client_reports_a_link_lost_while_idle(
    fake: FakeController, make_client: MakeClient, caplog: pytest.LogCaptureFixture
) -> None:
    rov = make_client()
    assert rov.depth_cm() == 123
    with caplog.at_level(logging.WARNING, logger="rovlink.client"):
        fake.close()  # the controller hangs up
        assert wait_until(lambda: rov.closed)
        assert wait_until(lambda: _REASON in caplog.text)
    with pytest.raises(ConnectionLostError, match=_REASON):
        rov.depth_cm()


async def test_the_asyncio_client_reports_a_link_lost_while_idle(
    fake: FakeController, make_async_client: MakeAsyncClient, caplog: pytest.LogCaptureFixture
) -> None:
    rov = await make_async_client()
    assert await rov.depth_cm() == 123
    with caplog.at_level(logging.WARNING, logger="rovlink.aio"):
        fake.close()
        assert await wait_until_async(lambda: rov.closed)
        assert _REASON in caplog.text
    with pytest.raises(ConnectionLostError, match=_REASON):
        await rov.depth_cm()
