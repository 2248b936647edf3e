"""An asyncio client that keeps track of what it sent and how its queries fared.

The driver sends frames and matches replies; the operator tools also need to know what was sent
(for the state "as last sent", and to show the bytes on screen) and how long replies took. The
driver has no hook for either, so :class:`TrackedClient` wraps it: every frame goes through here.
"""

from __future__ import annotations

import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from rovlink.aio import AsyncClient
from rovlink.client.operations import SENSORS, raw_frame
from rovlink.client.sensors import Sensors
from rovlink.piloting.commanded import CommandedState
from rovlink.piloting.health import LinkHealth
from rovlink.protocol import (
    DEFAULT_ALGORITHM,
    Command,
    Decoder,
    Frame,
    Response,
)

__all__ = ["SentCallback", "SentFrame", "TrackedClient"]


@dataclass(frozen=True, slots=True)
class SentFrame:
    """One frame as it went on the wire, the command in it, and why it may be dropped."""

    data: bytes
    #: ``None`` for a raw frame the controller will not take as a command.
    command: Command | None
    #: Why the controller will drop it, judged by the state as last sent; ``None`` if it won't.
    warning: str | None = None

    @property
    def text(self) -> str:
        """The frame as text, e.g. ``#qd8C!``."""
        return self.data.decode("ascii", errors="backslashreplace")


SentCallback = Callable[[SentFrame], None]


class TrackedClient:
    """An :class:`~rovlink.aio.AsyncClient` whose every frame updates :attr:`commanded`.

    ``algorithm`` must be the one the client was connected with (it is only used to show the
    frames as they are written). Queries are timed into :attr:`health`.

    Example::

        async with rovlink.aio.connect("sim://") as client:
            rov = TrackedClient(client)
            await rov.send(Command("start"))
            print(rov.commanded.lock_text())   # unlocked (as last sent)
    """

    def __init__(
        self,
        client: AsyncClient,
        *,
        algorithm: str = DEFAULT_ALGORITHM,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.client = client
        self.algorithm = algorithm
        self.commanded = CommandedState()
        self.health = LinkHealth()
        self._clock = clock
        self._listeners: list[SentCallback] = []

    def add_sent_listener(self, listener: SentCallback) -> None:
        """Call ``listener`` with every frame sent through this client, as it is sent."""
        self._listeners.append(listener)

    @property
    def checksum_enabled(self) -> bool:
        """Whether frames carry checksums now."""
        return self.client.checksum_enabled

    def now_s(self) -> float:
        """The clock the health figures are measured with."""
        return self._clock()

    # -- sending -------------------------------------------------------------------------------

    async def send(self, command: Command) -> tuple[Response, ...]:
        """Send a command of the table; a query returns its replies (see ``AsyncClient.send``).

        Raises what the driver raises: QueryTimeoutError after the retries, ConnectionLostError.
        """
        data = self.client.frame_for(command)
        if not command.spec.is_query or self.client.closed:
            replies = await self.client.send(command)  # a closed client raises here
            self._sent(data, command)
            return replies
        self._sent(data, command)  # shown before the reply, which may take a while
        return await self._timed(self.client.send(command))

    async def send_raw(self, frame: str | bytes) -> tuple[Response, ...]:
        """Send a frame exactly as given, once (see ``AsyncClient.send_raw``)."""
        data = raw_frame(frame)
        command = self._as_controller_reads(data)
        if command is not None and command.spec.is_query:
            self._sent(data, command)
            return await self._timed(self.client.send_raw(data))
        replies = await self.client.send_raw(data)
        self._sent(data, command)
        return replies

    async def stop(self) -> None:
        """``#stop!``, at once (it does not wait for anything queued before it)."""
        await self.send(Command("stop"))

    async def sensors(self) -> Sensors:
        """``#qsa!``: every sensor at once, timed into :attr:`health`."""
        return SENSORS.read(await self.send(SENSORS.command))

    # -- internals ------------------------------------------------------------------------------

    def _sent(self, data: bytes, command: Command | None) -> None:
        warning = self.commanded.apply(command) if command is not None else None
        sent = SentFrame(data, command, warning)
        for listener in self._listeners:
            listener(sent)

    async def _timed(self, request: Awaitable[tuple[Response, ...]]) -> tuple[Response, ...]:
        started_s = self._clock()
        try:
            replies = await request
        except TimeoutError as error:
            self.health.record_failure(str(error), self._clock())
            raise
        now_s = self._clock()
        self.health.record_reply(now_s - started_s, now_s)
        return replies

    def _as_controller_reads(self, data: bytes) -> Command | None:
        """The command the controller will take from a raw frame, in the current checksum mode.

        The decoder applies the protocol's rules, the bare ``#stop!`` of checksum mode included.
        """
        decoder = Decoder(checksum_enabled=self.checksum_enabled, algorithm=self.algorithm)
        events = decoder.feed(data)
        if (
            len(events) == 1
            and isinstance(events[0], Frame)
            and isinstance(events[0].message, Command)
        ):
            return events[0].message
        return None
