"""Hearing what other lines do to the lock: the controller's debug output, put on at a tool's
request (``--hear-other-lines``).

With debug output on, the controller announces every lock change to every line
(:mod:`rovlink.protocol.announcements`), and :class:`~rovlink.piloting.TrackedClient` takes
them into the state a tool shows. The protocol resets debug output to off with the controller
(P5), so it is put on again after a suspected reset and on a reopened link.
"""

from __future__ import annotations

import asyncio
import contextlib

from rovlink.aio import AsyncClient
from rovlink.client.errors import ClientError
from rovlink.client.events import ClientEvent, LinkState, ResetSuspected
from rovlink.logs import get_logger

__all__ = ["hear_other_lines"]

logger = get_logger("rovlink.piloting")


async def hear_other_lines(client: AsyncClient) -> None:
    """Put the controller's debug output on (``#debug1!``) now, and again after each suspected
    reset or reopened link. Debug output is the controller's, not the line's: every tool on it
    then reads the text (and skips it), and one tool's ``#debug0!`` silences it for all.

    Example::

        async with rovlink.aio.connect("socket://127.0.0.1:5760") as client:
            await hear_other_lines(client)
            rov = TrackedClient(client)   # rov.commanded now follows another line's #stop!
    """
    await client.set_debug(True)
    again: set[asyncio.Future[None]] = set()

    def on_event(event: ClientEvent) -> None:
        reset = isinstance(event, ResetSuspected)
        if reset or (isinstance(event, LinkState) and event.state == "reconnected"):
            task = asyncio.ensure_future(_debug_on_again(client))
            again.add(task)
            task.add_done_callback(again.discard)

    client.subscribe(on_event)


async def _debug_on_again(client: AsyncClient) -> None:
    with contextlib.suppress(ClientError, ConnectionError):  # (the link went again: next time)
        await client.set_debug(True)
        logger.info("debug output put on again, to hear other lines")
