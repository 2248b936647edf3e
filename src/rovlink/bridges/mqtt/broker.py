"""Where the broker is and how to log in: ``mqtt://HOST:PORT`` or ``mqtts://`` (TLS)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlsplit

__all__ = ["KEEPALIVE_S", "BrokerSettings", "parse_broker_url"]

_DEFAULT_PORTS = {"mqtt": 1883, "mqtts": 8883}
#: The MQTT keep-alive of the bridges and the fleet's table, s: a broker that goes silent (its
#: network gone) is noticed within one and a half of it, not paho-mqtt's default minute and more.
KEEPALIVE_S = 10


@dataclass(frozen=True, slots=True)
class BrokerSettings:
    """A broker's address, credentials and TLS options, checked."""

    host: str
    port: int = 1883
    tls: bool = False
    username: str | None = None
    password: str | None = None
    #: TLS: the CA certificates to trust (default: the system's), a client certificate and key.
    ca_file: Path | None = None
    cert_file: Path | None = None
    key_file: Path | None = None
    #: TLS: accept a certificate whose name does not match the host (test brokers only).
    insecure: bool = False

    def describe(self) -> str:
        """``mqtts://broker:8883``, a URL ``--broker`` takes, and the user if there is one
        (never the password), which ``--broker`` refuses in its URL: ``--username`` gives it.

        >>> BrokerSettings("::1", 1883).describe()
        'mqtt://[::1]:1883'
        >>> BrokerSettings("broker.example", 8883, tls=True, username="rov-1").describe()
        'mqtts://broker.example:8883 (as rov-1)'
        """
        host = f"[{self.host}]" if ":" in self.host else self.host  # (IPv6)
        user = f" (as {self.username})" if self.username else ""
        return f"{'mqtts' if self.tls else 'mqtt'}://{host}:{self.port}{user}"


def parse_broker_url(url: str) -> tuple[str, int, bool]:
    """Host, port and TLS of ``mqtt://HOST[:PORT]`` or ``mqtts://HOST[:PORT]``.

    >>> parse_broker_url("mqtt://localhost"), parse_broker_url("mqtts://broker.example:9000")
    (('localhost', 1883, False), ('broker.example', 9000, True))
    >>> parse_broker_url("http://localhost")
    Traceback (most recent call last):
    ...
    ValueError: broker 'http://localhost': expected mqtt://HOST[:PORT] or mqtts://HOST[:PORT]
    """
    expected = f"broker {url!r}: expected mqtt://HOST[:PORT] or mqtts://HOST[:PORT]"
    try:
        parts = urlsplit(url)
    except ValueError:  # (an unclosed "[" of an IPv6 address: urllib names no URL)
        raise ValueError(expected) from None
    if parts.scheme not in _DEFAULT_PORTS or not parts.hostname or parts.path not in ("", "/"):
        raise ValueError(expected)
    if parts.username or parts.password:
        raise ValueError(f"broker {url!r}: give the user with --username, not in the URL")
    try:
        port = parts.port
    except ValueError:
        port = 0
    if port is None:
        port = _DEFAULT_PORTS[parts.scheme]
    elif port == 0:  # not "the default": a broker cannot be reached on port 0
        raise ValueError(f"broker {url!r}: the port must be 1–65535")
    return parts.hostname, port, parts.scheme == "mqtts"
