"""One connection to the broker through aiomqtt, left with its socket closed however it ends.

aiomqtt gives up a connection without closing its socket when the broker's CONNACK does not come
in time, when the attempt is cancelled, or when its DISCONNECT cannot be written. A broker that
was only silent (stopped, overloaded) answers such a connection later, and what it sends lands
on a client nobody awaits any more: a CONNACK then a close set an exception on the client's
"disconnected" future that no one retrieves ("Future exception was never retrieved" when it is
collected, typically as the bridge exits), and a close after a cancelled attempt raises
``CancelledError`` in the event loop's reader callback. The connection, meanwhile, stays open on
the broker, with the bridge's client id and last will, served by no one.

aiomqtt makes the TCP connection and writes CONNECT in an executor thread, which a cancellation
does not stop: an attempt cancelled in its handshake (a SYN to an address that answers nothing,
a stopped broker whose queue of connections is full) goes on, and completes, or fails, up to
paho's connect timeout later. Completed, its socket is closed then: the broker that resumed would
otherwise take its CONNECT as this bridge's, and keep the connection open.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from rovlink.logs import get_logger

__all__ = ["broker_connection", "close_abandoned_socket"]

logger = get_logger("rovlink.bridges.mqtt")


@asynccontextmanager
async def broker_connection(client: Any) -> AsyncIterator[Any]:
    """``async with client`` (an ``aiomqtt.Client``): connected inside; on leaving, however it
    is left (an error, a timeout, a cancellation), the socket is closed if aiomqtt left it open,
    now or, from a handshake still under way, once it completes."""
    attempt = _ConnectAttempt(client, asyncio.get_running_loop())
    try:
        async with client:
            yield client
    finally:
        attempt.give_up()
        close_abandoned_socket(client)


class _ConnectAttempt:
    """aiomqtt's blocking connect (``client._client_connect``, run in an executor thread),
    wrapped so that a socket it opens after the connection was given up is closed."""

    def __init__(self, client: Any, loop: asyncio.AbstractEventLoop) -> None:
        self._client = client
        self._loop = loop
        self._lock = threading.Lock()
        self._given_up = False
        connect = getattr(client, "_client_connect", None)
        if connect is None:
            return  # (an aiomqtt that connects otherwise: nothing to wrap)

        def connect_then_check() -> None:
            try:
                connect()
            finally:
                with self._lock:
                    given_up = self._given_up
                if given_up:
                    self._close_late()

        client._client_connect = connect_then_check

    def give_up(self) -> None:
        """The connection is left: a socket the connect opens from now on is closed. (One it
        opened before is there for :func:`close_abandoned_socket`: the check comes after.)"""
        with self._lock:
            self._given_up = True

    def _close_late(self) -> None:
        """From the executor thread: close the socket in the event loop's thread (aiomqtt's
        socket callbacks use the loop), or here if the loop is closed."""
        try:
            self._loop.call_soon_threadsafe(close_abandoned_socket, self._client)
        except RuntimeError:  # the loop is closed
            with contextlib.suppress(Exception):  # (its socket callbacks need the loop)
                close_abandoned_socket(self._client)


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
