"""Fixtures: a scripted fake controller on a socket pair, and clients connected to it."""

from __future__ import annotations

import socket
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Iterator
from typing import Any

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, ClientOptions
from rovlink.client.links import SocketLink
from tests.client.fake_controller import FakeController

# Short enough to keep timeout tests fast, long enough for a loaded machine to answer.
TEST_TIMEOUT_S = 0.25


def wait_until(predicate: Callable[[], bool], timeout_s: float = 2.0) -> bool:
    """Poll a condition that has no notification of its own, until it holds or time runs out."""
    deadline = time.monotonic() + timeout_s
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.005)
    return True


@pytest.fixture
def fake_pair() -> Iterator[tuple[FakeController, socket.socket]]:
    fake, sock = FakeController.on_socketpair()
    yield fake, sock
    fake.close()


@pytest.fixture
def fake(fake_pair: tuple[FakeController, socket.socket]) -> FakeController:
    return fake_pair[0]


def _options(overrides: dict[str, Any]) -> ClientOptions:
    settings: dict[str, Any] = {"timeout_s": TEST_TIMEOUT_S, "keepalive_s": None}
    settings.update(overrides)
    return ClientOptions(**settings)


@pytest.fixture
def make_client(fake_pair: tuple[FakeController, socket.socket],
                ) -> Iterator[Callable[..., Client]]:
    """Connect a blocking client to the fake: ``make_client(checksum=True, ...)``."""
    clients: list[Client] = []

    def make(**overrides: Any) -> Client:
        client = Client(SocketLink(fake_pair[1], "socket pair"), _options(overrides))
        clients.append(client)
        return client

    yield make
    for client in clients:
        client.close()


@pytest.fixture
async def make_async_client(fake_pair: tuple[FakeController, socket.socket],
                            ) -> AsyncIterator[Callable[..., Awaitable[AsyncClient]]]:
    """Connect an asyncio client to the fake: ``await make_async_client(checksum=True)``."""
    clients: list[AsyncClient] = []

    async def make(max_in_flight: int = 8, **overrides: Any) -> AsyncClient:
        client = AsyncClient(SocketLink(fake_pair[1], "socket pair"), _options(overrides),
                             max_in_flight=max_in_flight)
        clients.append(client)
        return await client.open()

    yield make
    for client in clients:
        await client.close()
