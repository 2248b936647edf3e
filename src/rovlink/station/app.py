"""The Starlette application: the pilot's page, its static assets and the ``/ws`` WebSocket.

Every request passes :class:`AccessGuard` first (:mod:`rovlink.station.access`); the page and
its assets are files of this package (no network needed: the robot's laptop is often offline).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from importlib import resources
from typing import Any

from starlette.applications import Starlette
from starlette.responses import (
    FileResponse,
    HTMLResponse,
    PlainTextResponse,
    RedirectResponse,
    Response,
)
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.types import ASGIApp, Receive, Scope, Send
from starlette.websockets import WebSocket, WebSocketDisconnect

from rovlink.station.access import Access
from rovlink.station.hub import Station
from rovlink.station.messages import MessageError, parse_stop

__all__ = ["STATIC_DIRECTORY", "AccessGuard", "build_app"]

logger = logging.getLogger(__name__)

#: The page's files, shipped in the package.
STATIC_DIRECTORY = str(resources.files("rovlink.station") / "static")

#: The page must not be cached across versions of the station (its script names do not change).
_NO_STORE = {"Cache-Control": "no-store"}
_SECURITY_HEADERS = {
    "Content-Security-Policy": (
        "default-src 'self'; connect-src 'self'; img-src 'self' data:; "
        "style-src 'self' 'unsafe-inline'; frame-ancestors 'none'"
    ),
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
}


class AccessGuard:
    """ASGI middleware: a request the :class:`Access` rules refuse never reaches the app."""

    def __init__(self, app: ASGIApp, access: Access) -> None:
        self.app = app
        self.access = access

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        kind = scope["type"]
        if kind not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        query = scope.get("query_string", b"").decode("latin-1")
        verdict = self.access.check(scope["headers"], query, websocket=kind == "websocket")
        if not verdict.allowed:
            logger.warning("refused %s %s: %s", kind, scope.get("path"), verdict.reason)
            if kind == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": verdict.reason})
                return
            response: Response = PlainTextResponse(
                f"rovlink web: {verdict.reason}\n", status_code=403, headers=_NO_STORE
            )
            await response(scope, receive, send)
            return
        if verdict.token_in_url and kind == "http":
            # Keep the token in a cookie for this port and take it out of the address bar.
            response = RedirectResponse(scope.get("path", "/"), status_code=303)
            response.set_cookie(
                self.access.cookie_name, self.access.token or "", httponly=True, samesite="strict"
            )
            await response(scope, receive, send)
            return
        await self.app(scope, receive, send)


def build_app(station: Station, access: Access) -> ASGIApp:
    """The station's ASGI application for ``station``, behind ``access``'s checks."""
    index_html = (resources.files("rovlink.station") / "static" / "index.html").read_text(
        encoding="utf-8"
    )

    async def index(request: Any) -> Response:
        del request
        return HTMLResponse(index_html, headers={**_NO_STORE, **_SECURITY_HEADERS})

    async def socket(websocket: WebSocket) -> None:
        await _serve_page(station, websocket)

    async def stop(websocket: WebSocket) -> None:
        await _serve_stop(station, websocket)

    async def recording(request: Any) -> Response:
        # Only a finished recording of this station, by its name: never a path from the page.
        name = request.path_params["name"]
        path = station.recordings.file(name) if station.recordings is not None else None
        if path is None:
            return PlainTextResponse(
                f"rovlink web: no finished recording called {name!r}\n", status_code=404
            )
        return FileResponse(
            path, media_type="application/octet-stream", filename=name, headers=_NO_STORE
        )

    app = Starlette(
        routes=[
            Route("/", index),
            Mount("/static", StaticFiles(directory=STATIC_DIRECTORY), name="static"),
            Route("/recordings/{name}", recording),
            WebSocketRoute("/stop", stop),
            WebSocketRoute("/ws", socket),
        ]
    )
    return AccessGuard(app, access)


#: How long a STOP's own connection may take to say which STOP it is.
_STOP_MESSAGE_TIMEOUT_S = 5.0


async def _serve_stop(station: Station, websocket: WebSocket) -> None:
    """A page's STOP on a WebSocket of its own (``/stop``): one message, ``{"stop_id": ...,
    "page_id": ...}``, answered ``stopped`` (or with what was wrong), then closed.

    A WebSocket, not an HTTP request: a browser opens a new connection for every WebSocket,
    while a request may go on a kept-alive connection as dead as the page's socket (see
    :meth:`Station.stop_on_its_own`). The access checks are the page socket's (the same
    origin, the token).
    """
    await websocket.accept()
    try:
        message = await asyncio.wait_for(websocket.receive(), _STOP_MESSAGE_TIMEOUT_S)
        text = message.get("text")
        if message["type"] == "websocket.disconnect" or not isinstance(text, str):
            return
        try:
            stop_id, page_id = parse_stop(text)
        except MessageError as error:
            await websocket.send_text(f"refused: {error}")
        else:
            client = websocket.client
            await station.stop_on_its_own(stop_id, page_id, client.host if client else "unknown")
            await websocket.send_text("stopped")
        await websocket.close()
    except (asyncio.TimeoutError, WebSocketDisconnect):
        return


async def _serve_page(station: Station, websocket: WebSocket) -> None:
    """One page's WebSocket: its messages to the station, the station's to it.

    Three ways it ends: the page closes it (or it drops), the page floods the station, or the
    page falls so far behind that its outbox overflows (:mod:`rovlink.station.outbox`). The
    last is noticed at once, not when the write stuck behind the slow page returns: the page
    leaves the station (a pilot's thrust to zero) before its socket is closed.
    """

    await websocket.accept()
    client = websocket.client
    peer = station.join(client.host if client is not None else "unknown")

    async def write() -> None:
        while True:
            message = await peer.outbox.get()
            await websocket.send_text(json.dumps(message, separators=(",", ":")))

    async def read() -> str | None:
        """Until the page goes; why it must be closed, if it must (``None``: it closed)."""
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                return None
            if not await station.handle(peer, message.get("text", message.get("bytes"))):
                return "too many messages"
            # Messages already received are handed over without a pause: without this one, a
            # page that floods the station would hold the event loop, and with it the polls,
            # the watchdog and every other page, for as long as it keeps sending.
            await asyncio.sleep(0)

    reader = asyncio.ensure_future(read())
    tasks = {
        reader,
        asyncio.ensure_future(write()),
        asyncio.ensure_future(peer.outbox.wait_overflow()),
    }
    closing: tuple[int, str] | None = None  # the close frame's code and reason, if one is due
    try:
        done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        if peer.outbox.overflowed:
            closing = (1013, "too far behind: reconnect for the whole state")
        elif reader in done and not reader.exception() and reader.result() is not None:
            closing = (1008, reader.result() or "")
        # Otherwise the socket went: the page closed it, or a send found it gone.
        for task in done:
            if not task.cancelled() and task.exception() is not None:
                logger.debug("%s: its connection ended: %r", peer.label, task.exception())
    finally:
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        await station.leave(peer)
    if closing is not None:
        with contextlib.suppress(Exception):  # the socket may have gone meanwhile
            await websocket.close(code=closing[0], reason=closing[1])
