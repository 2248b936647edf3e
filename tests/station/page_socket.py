"""A WebSocket client that speaks the station's protocol, as a page does (for the server tests)."""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import Callable
from typing import Any

from websockets.asyncio.client import ClientConnection, connect

Message = dict[str, Any]


class PageSocket:
    """One page's WebSocket: every message from the station is kept, in order."""

    def __init__(self, connection: ClientConnection) -> None:
        self.connection = connection
        self.messages: list[Message] = []
        self._arrived = asyncio.Condition()
        self._reader = asyncio.ensure_future(self._read())
        self.hello: Message = {}

    @classmethod
    async def open(cls, url: str, **options: Any) -> PageSocket:
        page = cls(await connect(url, **options))
        page.hello = await page.next("hello")
        return page

    @property
    def id(self) -> str:
        return str(self.hello["id"])

    async def _read(self) -> None:
        with contextlib.suppress(Exception):
            async for text in self.connection:
                async with self._arrived:
                    self.messages.append(json.loads(text))
                    self._arrived.notify_all()

    async def send(self, message: Message | str | bytes) -> None:
        await self.connection.send(
            message if isinstance(message, str | bytes) else json.dumps(message)
        )

    async def next(
        self, kind: str, matches: Callable[[Message], bool] = lambda _: True, timeout_s: float = 5.0
    ) -> Message:
        """The first message of ``kind`` that matches; it and those before it are taken."""

        def found() -> Message | None:
            for index, message in enumerate(self.messages):
                if message.get("type") == kind and matches(message):
                    del self.messages[: index + 1]
                    return message
            return None

        result: list[Message] = []

        def ready() -> bool:
            message = found()
            if message is not None:
                result.append(message)
            return bool(result)

        async with self._arrived:
            await asyncio.wait_for(self._arrived.wait_for(ready), timeout_s)
        return result[0]

    async def close(self) -> None:
        await self.connection.close()
        self._reader.cancel()
