"""An asyncio client that keeps track of what it sent and how its queries fared.

The driver sends frames and matches replies; the operator tools also need to know what was sent
(for the state "as last sent", and to show the bytes on screen) and how long replies took. They
read what was sent from the driver's one hook (``BytesSent`` events, with the command the
session read in the bytes, raw frames included), so nothing here decodes a frame again; the
queries sent through :class:`TrackedClient` are timed into its link health.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections import deque
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from rovlink.aio import AsyncClient
from rovlink.client.events import (
    BytesSent,
    ClientEvent,
    LinkState,
    QueryFailed,
    ReplyReceived,
    ResetSuspected,
    Unsolicited,
)
from rovlink.client.operations import SENSORS, raw_frame
from rovlink.client.sensors import Sensors
from rovlink.piloting.commanded import CommandedState
from rovlink.piloting.health import LinkHealth
from rovlink.protocol import DEFAULT_ALGORITHM, Command, Response, Text
from rovlink.protocol.announcements import Announcement, read_announcement

__all__ = [
    "LEAVING_REPLY_WAIT_S",
    "REOPENED_NOTICE",
    "STOP_KEPT_NOTICE",
    "STOP_UNSENT_NOTICE",
    "HeardCallback",
    "SentCallback",
    "SentFrame",
    "TrackedClient",
]

#: What a tool says once a lost link is reopened (the state as last sent is then forgotten).
REOPENED_NOTICE = (
    "link reopened: the controller may have reset (locked) or stopped on its own failsafe,"
    " and the motion was zeroed; send start to move again"
)

#: What a tool says of a #stop! asked for while the link is down: it is not on the wire yet.
STOP_KEPT_NOTICE = (
    "link lost: #stop! is sent as soon as the link is reopened; until then the controller's"
    " link-loss failsafe (P17) is what stops the motors"
)

#: What a tool says when it leaves, unlocked, while the link is down: its #stop! never went.
STOP_UNSENT_NOTICE = (
    "#stop! could not be sent: the link is lost; the controller's link-loss failsafe (P17)"
    " is what stops the motors"
)

#: How long a tool that leaves waits for the replies to its queries still on the wire: long
#: enough for a controller that answers, not the whole reply timeout of one that does not.
LEAVING_REPLY_WAIT_S = 1.0


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
#: Called with an announcement of the controller's that changed the lock a tool shows.
HeardCallback = Callable[[Announcement], None]


class TrackedClient:
    """An :class:`~rovlink.aio.AsyncClient` whose every frame sent updates :attr:`commanded`.

    It subscribes to the client's events: every frame written — by it, by another user of the
    client, or by the session itself (zero thrust after ``motion_timeout``) — updates the state
    and reaches the sent listeners; the session's keep-alives and fences do not. ``algorithm``
    is the one the client was connected with, for the tools to name. Queries sent through it are
    timed into :attr:`health`. With debug output on, what the controller announces to every
    line (the lock changing) updates the state too (:meth:`CommandedState.hear`) and reaches
    the heard listeners; it never makes this client send anything.

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
        self._heard_listeners: list[HeardCallback] = []
        #: The link was lost and is being reopened (the client was connected with reconnect).
        self.link_down = False
        self._stopped_while_down = False
        self._sent_while_down = False  # a frame of the tool's own went on the reopened link
        #: The tool's own queries on the wire, and the names of the driver's queries written
        #: while there were none: keep-alives, whose outcome says whether the link answers
        #: when the tool asks nothing (a fence, written as a query of the tool's fails, is
        #: left out: a reply to it would hide that failure).
        self._own_queries = 0
        self._idle_queries: deque[str] = deque()
        client.subscribe(self._on_event)

    def add_sent_listener(self, listener: SentCallback) -> None:
        """Call ``listener`` with every frame sent through this client, as it is sent."""
        self._listeners.append(listener)

    def add_heard_listener(self, listener: HeardCallback) -> None:
        """Call ``listener`` with each announcement of the controller's (debug output on) that
        changed the lock shown, once :attr:`commanded` has taken it."""
        self._heard_listeners.append(listener)

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
        return await self._timed(self.client.send(command))

    async def send_raw(self, frame: str | bytes) -> tuple[Response, ...]:
        """Send a frame exactly as given, once (see ``AsyncClient.send_raw``)."""
        return await self._timed(self.client.send_raw(raw_frame(frame)))

    async def stop(self) -> None:
        """``#stop!``, at once (it does not wait for anything queued before it)."""
        await self.send(Command("stop"))

    async def close(self) -> None:
        """Close the client for a tool that leaves: the replies to queries still on the wire
        get :data:`LEAVING_REPLY_WAIT_S`, not the whole reply timeout (``--timeout`` may be an
        hour), and the port is released all the same."""
        with contextlib.suppress(asyncio.TimeoutError):  # (not TimeoutError on 3.10)
            await asyncio.wait_for(self.client.close(), LEAVING_REPLY_WAIT_S)

    async def sensors(self) -> Sensors:
        """``#qsa!``: every sensor at once, timed into :attr:`health`."""
        return SENSORS.read(await self.send(SENSORS.command))

    # -- internals ------------------------------------------------------------------------------

    def _on_event(self, event: ClientEvent) -> None:
        if isinstance(event, ResetSuspected):
            # (Locked after a reset, P21: the state as last sent no longer holds.)
            self.commanded.forget_after_reset()
            return
        if isinstance(event, LinkState):
            self._on_link_state(event.state)
            return
        if isinstance(event, ReplyReceived | QueryFailed):
            # (A console that is only typed into queries nothing: its link would show the last
            # reply it asked for, "ok", while the controller had long gone silent.)
            idle = self._idle_queries
            if idle and event.query.name == idle[0]:
                idle.popleft()
                if isinstance(event, ReplyReceived):
                    self.health.record_heard(self._clock())
                else:
                    self.health.record_unanswered(f"{event.query}: {event.outcome}")
            return
        if not isinstance(event, BytesSent):
            if isinstance(event, Unsolicited) and isinstance(event.event, Text):
                self._on_text(event.event.text)  # (text only: replies never get here)
            return
        command = event.command
        if event.by_session and command is not None and command.spec.is_query:
            if not self._own_queries:
                self._idle_queries.append(command.name)
            return
        # A #stop! asked for while the link was down goes first on the reopened one, written
        # by the driver but the operator's all the same: it is "last sent".
        kept_stop = self.link_down and command is not None and command.name == "stop"
        if kept_stop:
            self._stopped_while_down = True
        if event.by_session and not kept_stop:
            # The driver's own frames: keep-alives and fences are left out; the others (#crcoff!
            # re-asserted, zero thrust after motion_timeout) change the state and are shown as
            # sent, but "last sent" stays the operator's.
            if command is None or command.spec.is_query:
                return
            self._tell(SentFrame(event.data, command, self.commanded.apply(command, own=False)))
            return
        if self.link_down:
            self._sent_while_down = True  # (the reopened link's first frames: a kept #stop!)
        if command is None or not _one_whole_frame(event.data):
            # A raw write whose effect is unknown: a partial frame may complete one already in
            # the controller's buffer (raw #sta, then raw rt! is #start!).
            self.commanded.forget_lock("a raw write whose effect is not known")
        warning = self.commanded.apply(command) if command is not None else None
        self._tell(SentFrame(event.data, command, warning))

    def _on_text(self, text: str) -> None:
        announcement = read_announcement(text)
        if announcement is None or not self.commanded.hear(announcement):
            return
        for listener in self._heard_listeners:
            listener(announcement)

    def _on_link_state(self, state: str) -> None:
        self._idle_queries.clear()  # (what was on the old link never settles)
        if state == "lost":
            self.link_down = True
            self._stopped_while_down = self._sent_while_down = False
        elif state == "reconnected":
            self.link_down = False
            self.commanded.forget_after_reopening(
                stopped=self._stopped_while_down, sent_on_it=self._sent_while_down
            )

    def _tell(self, sent: SentFrame) -> None:
        for listener in self._listeners:
            listener(sent)

    async def _timed(self, request: Awaitable[tuple[Response, ...]]) -> tuple[Response, ...]:
        started_s = self._clock()
        self._own_queries += 1
        try:
            replies = await request
        except TimeoutError as error:
            self.health.record_failure(str(error), self._clock())
            raise
        finally:
            self._own_queries -= 1
        if replies:  # a query's (a set command has none)
            now_s = self._clock()
            self.health.record_reply(now_s - started_s, now_s)
        return replies


def _one_whole_frame(data: bytes) -> bool:
    """Whether ``data`` is one command frame and nothing else (spaces around it aside)."""
    frame = data.strip()
    return (
        frame.startswith(b"#")
        and frame.endswith(b"!")
        and frame.count(b"#") == 1
        and (frame.count(b"!") == 1)
    )
