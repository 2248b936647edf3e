"""Who may use the station: the checks on every HTTP request and WebSocket, before the app.

* Bound to a loopback address (the default) only this computer can connect; the ``Host``
  header must name a loopback address too, so a web page served elsewhere cannot reach the
  station through a DNS name that it points at 127.0.0.1 (DNS rebinding).
* On any other address a token is required (generated and printed as a URL, as Jupyter does,
  or given with ``--token``). The page's URL carries it once (``/?token=...``); the server then
  sets it as a cookie for this port and redirects to the bare URL. The WebSocket accepts the
  cookie or a ``token`` query parameter (for programs). Tokens are compared in constant time.
* A WebSocket that a browser opens from another origin is refused (browsers do not apply the
  same-origin policy to WebSockets: without this check any page the pilot visits could connect).

A refused HTTP request gets a 403 page saying why; a refused WebSocket is closed before it is
accepted (the browser sees HTTP 403). Nothing of the app runs for either.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
from collections.abc import Iterable
from dataclasses import dataclass
from http.cookies import SimpleCookie
from urllib.parse import parse_qs, urlsplit

__all__ = ["Access", "Verdict", "generate_token", "is_loopback"]

_LOOPBACK_NAMES = ("localhost",)
#: Bytes of randomness in a generated token (as text, 4/3 as many characters).
_TOKEN_BYTES = 24


def generate_token() -> str:
    """A fresh random token for a URL."""
    return secrets.token_urlsafe(_TOKEN_BYTES)


def is_loopback(host: str) -> bool:
    """Whether ``host`` (an address or ``localhost``) is this computer only.

    >>> is_loopback("127.0.0.1"), is_loopback("::1"), is_loopback("0.0.0.0")
    (True, True, False)
    """
    if host.lower() in _LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def _host_name(host_header: str) -> str:
    """``example.org`` from ``example.org:8600``, ``::1`` from ``[::1]:8600``."""
    return urlsplit(f"//{host_header}").hostname or ""


@dataclass(frozen=True, slots=True)
class Verdict:
    """Whether a request may go on; ``reason`` says why not."""

    allowed: bool
    reason: str = ""
    #: The token came in the URL: set the cookie and redirect to the bare URL.
    token_in_url: bool = False


_ALLOW = Verdict(True)


@dataclass(frozen=True, slots=True)
class Access:
    """The station's access rules: bound address, port and token (``None``: none needed).

    >>> access = Access(bind_host="0.0.0.0", port=8600, token="s3cret-token")
    >>> access.check(headers=[(b"host", b"10.0.0.5:8600")], query="", websocket=False).reason
    'a token is needed: open the URL that rovlink web printed (it ends in ?token=...)'
    >>> access.check([(b"host", b"10.0.0.5:8600")], "token=s3cret-token", websocket=False).allowed
    True
    """

    bind_host: str
    port: int
    token: str | None = None

    def __post_init__(self) -> None:
        if self.token is None and not is_loopback(self.bind_host):
            raise ValueError(
                f"serving on {self.bind_host}, beyond this computer, needs a token "
                "(a generated one, or --token)"
            )
        if self.token is not None and len(self.token) < 8:
            raise ValueError("a token must be at least 8 characters")

    @property
    def cookie_name(self) -> str:
        """The cookie the page's token is kept in (cookies are not kept apart by port)."""
        return f"rovlink-station-{self.port}"

    def check(
        self, headers: Iterable[tuple[bytes, bytes]], query: str, *, websocket: bool
    ) -> Verdict:
        """Whether a request with these headers and query string may use the station."""
        fields: dict[bytes, bytes] = {}
        for name, value in headers:
            fields.setdefault(name.lower(), value)
        host = fields.get(b"host", b"").decode("latin-1")
        if is_loopback(self.bind_host) and not is_loopback(_host_name(host)):
            return Verdict(False, f"this station serves this computer only, not host {host!r}")
        if websocket:
            origin = fields.get(b"origin")
            if origin is not None and not self._same_origin(origin.decode("latin-1"), host):
                return Verdict(False, f"WebSocket from another origin refused: {origin!r:.80}")
        if self.token is None:
            return _ALLOW
        url_tokens = parse_qs(query).get("token", [])
        if url_tokens:
            if self._matches(url_tokens[0]):
                return Verdict(True, token_in_url=True)
            return Verdict(False, "wrong token")
        if self._matches(self._cookie_token(fields.get(b"cookie", b""))):
            return _ALLOW
        return Verdict(
            False,
            "a token is needed: open the URL that rovlink web printed (it ends in ?token=...)",
        )

    def _matches(self, offered: str | None) -> bool:
        assert self.token is not None
        if offered is None:
            return False
        return hmac.compare_digest(offered.encode(), self.token.encode())

    def _cookie_token(self, header: bytes) -> str | None:
        cookie: SimpleCookie = SimpleCookie()
        try:
            cookie.load(header.decode("latin-1"))
        except Exception:  # a malformed cookie header is no token, never a crash
            return None
        morsel = cookie.get(self.cookie_name)
        return morsel.value if morsel is not None else None

    @staticmethod
    def _same_origin(origin: str, host: str) -> bool:
        parts = urlsplit(origin)
        return parts.scheme in ("http", "https") and parts.netloc.lower() == host.lower()
