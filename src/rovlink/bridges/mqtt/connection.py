"""One connection to the broker through aiomqtt, left with its socket closed however it ends.

aiomqtt gives up a connection without closing its socket when the broker's CONNACK does not come
in time, when the attempt is cancelled, or when its DISCONNECT cannot be written. A broker that
was only silent (stopped, overloaded) answers such a connection later, and what it sends lands
on a client nobody awaits any more: a CONNACK then a close set an exception on the client's
"disconnected" future that no one retrieves ("Future exception was never retrieved" when it is
collected, typically as the bridge exits), and a close after a cancelled attempt raises
``CancelledError`` in the event loop's reader callback. The connection, meanwhile, stays open on
the broker, with the bridge's client id and last will, served by no one.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from rovlink.logs import get_logger

__all__ = ["broker_connection", "close_abandoned_socket"]

logger = get_logger("rovlink.bridges.mqtt")


@asynccontextmanager
async def broker_connection(client: Any) -> AsyncIterator[Any]:
    """``async with client`` (an ``aiomqtt.Client``): connected inside; on leaving, however it
    is left (an error, a timeout, a cancellation), the socket is closed if aiomqtt left it open."""
    try:
        async with client:
            yield client
    finally:
        close_abandoned_socket(client)


def close_abandoned_socket(client: Any) -> bool:
    """Close the socket that ``client`` (an ``aiomqtt.Client`` no longer used) left open, so
    that nothing the broker sends on it later reaches the client; whether there was one.

    paho's own close is used: it also unregisters the socket from the event loop (through
    aiomqtt's socket callbacks) and calls no disconnect callback.
    """
    paho = getattr(client, "_client", None)
    if paho is None or paho.socket() is None:
        return False  # (a clean disconnect, or a broker that closed it, has closed it already)
    logger.debug("closing a broker connection given up: its socket was left open")
    paho._sock_close()  # (paho has no public close that calls no callback)
    return True
