"""Serve the station: connect to the robot, bind the address, run uvicorn until told to stop.

The socket is bound here (not by uvicorn) so that ``--port 0`` can pick a free port and the
URL printed is the one that works; the robot is connected first, so a wrong serial port is a
one-line error before anything listens.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import socket
from collections.abc import Awaitable, Callable, Generator
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from urllib.parse import quote

import uvicorn

from rovlink.aio import AsyncClient
from rovlink.piloting import TrackedClient
from rovlink.station.access import Access
from rovlink.station.app import build_app
from rovlink.station.hub import TELEMETRY_LOST_S, Station
from rovlink.station.messages import MAX_MESSAGE_BYTES
from rovlink.station.recording import StationRecordings

__all__ = ["ServeOptions", "StationFailedError", "bind", "page_urls", "serve"]

logger = logging.getLogger(__name__)


class StationFailedError(Exception):
    """The station's polling or watchdog failed: it shut down (``#stop!`` sent unless locked
    as last sent), and the command that served it failed."""


@dataclass(frozen=True, slots=True)
class ServeOptions:
    """Where and how to serve: address, port (0: any free one), token (``None``: none, on
    loopback only), sensor polls a second, the link's checksum algorithm (to name it), and the
    directory of the record button's recordings (``None``: no record button)."""

    host: str
    port: int
    token: str | None
    rate_hz: float
    algorithm: str
    recordings_dir: Path | None = None
    #: A controller that answers nothing for this long is stopped (see
    #: :func:`rovlink.station.hub.telemetry_lost_after`).
    telemetry_lost_s: float = TELEMETRY_LOST_S


class _Server(uvicorn.Server):
    """uvicorn's server, except that SIGINT, SIGTERM, SIGHUP and SIGQUIT only end the serving:
    uvicorn would raise the signal again as soon as it stops, and SIGTERM's default action would
    end the process before the station has sent ``#stop!`` and closed the link. :attr:`interrupted`:
    whether the signal that ended it was Ctrl-C or Ctrl-\\ (the command's status is then 130);
    :attr:`signalled`: whether a signal ended it at all."""

    interrupted = False
    signalled = False

    def __init__(
        self, config: uvicorn.Config, *, stop_robot: Callable[[], Awaitable[None]]
    ) -> None:
        super().__init__(config)
        self._stop_robot = stop_robot
        self._stopping: asyncio.Future[None] | None = None

    def handle_exit(self, sig: int, frame: FrameType | None) -> None:
        # Any Ctrl-C counts, also one after another ending signal: the kernel hands pending
        # signals over lowest number first, so a Ctrl-C and a closed terminal at once arrive
        # as SIGHUP then SIGINT, and the status depended on that race.
        if sig == signal.SIGINT or sig == getattr(signal, "SIGQUIT", None):  # (Ctrl-C, Ctrl-\\)
            self.interrupted = True
        self.signalled = True
        super().handle_exit(sig, frame)
        try:
            asyncio.get_running_loop()
        except RuntimeError:  # (not from the loop's signal handler: shutdown() stops it)
            return
        self._robot_stopped()  # at once, not at the serving loop's next tick

    async def shutdown(self, sockets: list[socket.socket] | None = None) -> None:
        # The robot is stopped before the pages' connections are closed: uvicorn waits for
        # them, up to its graceful timeout for one whose socket is stuck behind full buffers,
        # and the station's #stop! waited with them.
        try:
            await self._robot_stopped()
        except Exception:
            logger.exception("stopping the robot before closing the pages failed")
        await super().shutdown(sockets)

    def _robot_stopped(self) -> asyncio.Future[None]:
        if self._stopping is None:
            self._stopping = asyncio.ensure_future(self._stop_robot())
        return self._stopping

    @contextlib.contextmanager
    def capture_signals(self) -> Generator[None, None, None]:
        loop = asyncio.get_running_loop()
        previous = {number: signal.getsignal(number) for number in _ENDING_SIGNALS}
        for number in _ENDING_SIGNALS:
            loop.add_signal_handler(number, self.handle_exit, number, None)
        try:
            yield
        finally:
            for number in _ENDING_SIGNALS:
                loop.remove_signal_handler(number)
                # remove_signal_handler leaves SIGTERM at its default action, which would end
                # the process before the station has stopped the robot: what was there before.
                if previous[number] is not None:  # (None: not set from Python)
                    signal.signal(number, previous[number])


#: What ends the serving gracefully. SIGHUP (a closed terminal) too: left to the command line's
#: own handler, it cancelled the station mid-way through a graceful shutdown.
_ENDING_SIGNALS = tuple(
    getattr(signal, name)
    for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT")
    if hasattr(signal, name)
)


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host``:``port`` (OSError if taken or not ours); an IPv6
    address may come in brackets, as in a URL (``[::1]``)."""
    address = _unbracketed(host)
    family = socket.AF_INET6 if ":" in address else socket.AF_INET
    listener = socket.socket(family, socket.SOCK_STREAM)
    try:
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind((address, port))
        listener.listen(64)
    except OSError:
        listener.close()
        raise
    listener.setblocking(False)
    return listener


def _unbracketed(host: str) -> str:
    """``::1`` from ``[::1]``; any other host as it is.

    >>> _unbracketed("[::1]"), _unbracketed("::1"), _unbracketed("localhost")
    ('::1', '::1', 'localhost')
    """
    return host[1:-1] if host.startswith("[") and host.endswith("]") else host


def page_urls(host: str, port: int, token: str | None) -> list[str]:
    """The URLs to open the page at: the token in the query, as Jupyter prints them.

    >>> page_urls("127.0.0.1", 8600, None)
    ['http://127.0.0.1:8600/']
    >>> page_urls("0.0.0.0", 8600, "abc")[1]
    'http://127.0.0.1:8600/?token=abc'
    >>> page_urls("127.0.0.1", 8600, "a b&c")  # a token the user chose, quoted for the URL
    ['http://127.0.0.1:8600/?token=a%20b%26c']
    >>> page_urls("[::1]", 8600, None), page_urls("::1", 8600, None)
    (['http://[::1]:8600/'], ['http://[::1]:8600/'])
    """
    host = _unbracketed(host)
    suffix = f"?token={quote(token, safe='')}" if token is not None else ""
    shown = f"[{host}]" if ":" in host else host
    if host in ("0.0.0.0", "::"):
        return [
            f"http://{socket.gethostname()}:{port}/{suffix}",
            f"http://127.0.0.1:{port}/{suffix}",
        ]
    return [f"http://{shown}:{port}/{suffix}"]


async def serve(
    connect: Callable[[], Awaitable[AsyncClient]],
    options: ServeOptions,
    *,
    description: str,
    ready: Callable[[list[str]], None],
) -> str | None:
    """Connect, then serve until SIGINT, SIGTERM or SIGHUP; ``ready`` gets the page's URLs
    once listening. How it ended: ``interrupted`` (Ctrl-C or Ctrl-\\), ``stopped`` (SIGTERM,
    SIGHUP: a service stopped), or ``None`` (the server ended by itself); StationFailedError if
    the station's polling or watchdog failed (which ends the serving).

    On the way out the relay is disarmed and ``#stop!`` (every output to zero, the motors
    locked) is sent unless the robot is locked as last sent; then the link is closed.
    """
    access = Access(bind_host=options.host, port=options.port, token=options.token)
    client = await connect()
    try:
        listener = bind(options.host, options.port)
        port = listener.getsockname()[1]
        if port != options.port:  # port 0: the cookie's name follows the real port
            access = Access(bind_host=options.host, port=port, token=options.token)
        tracked = TrackedClient(client, algorithm=options.algorithm)
        recordings = None
        if options.recordings_dir is not None:
            recordings = StationRecordings(
                options.recordings_dir,
                url=description,
                checksum=client.checksum_enabled,
                algorithm=options.algorithm,
            )
        station = Station(
            tracked,
            description=description,
            rate_hz=options.rate_hz,
            recordings=recordings,
            telemetry_lost_s=options.telemetry_lost_s,
        )
        config = uvicorn.Config(
            build_app(station, access),
            log_level="warning",
            lifespan="off",
            ws="websockets-sansio",
            ws_max_size=MAX_MESSAGE_BYTES * 4,
            ws_ping_interval=5.0,
            ws_ping_timeout=5.0,
            timeout_graceful_shutdown=1,
        )
        await station.lock_at_start()
        server = _Server(config, stop_robot=station.stop_first)
        running = asyncio.ensure_future(station.run())
        # Without its watchdog the station must not go on serving: it shuts down (and sends
        # #stop! on the way out).
        running.add_done_callback(lambda _: setattr(server, "should_exit", True))
        failure: Exception | None = None
        try:
            serving = asyncio.ensure_future(server.serve(sockets=[listener]))
            while not server.started and not serving.done():
                await asyncio.sleep(0.01)
            if server.started:
                ready(page_urls(options.host, port, options.token))
            await serving
        finally:
            running.cancel()
            try:
                await running
            except asyncio.CancelledError:
                pass
            except Exception as error:
                logger.exception("the station's polling or watchdog failed; shutting down")
                failure = error
            await station.shutdown()
            listener.close()
    finally:
        await client.close()
    if failure is not None:
        raise StationFailedError(
            f"the station's polling or watchdog failed ({type(failure).__name__}: {failure})"
        ) from failure
    if server.interrupted:
        return "interrupted"
    return "stopped" if server.signalled else None
