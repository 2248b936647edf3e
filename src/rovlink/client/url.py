"""Connection URLs: what ``rovlink.connect`` opens, parsed and checked before anything is opened.

* a serial device path (``/dev/ttyUSB0``, ``COM3``, a pseudo-terminal's path) or any pyserial URL
  (``loop://``, ``rfc2217://host:port``, ``spy://…``), with ``?baudrate=N`` (default 115200);
* ``socket://host:port`` — TCP, opened natively with Nagle's algorithm off, so small frames are
  not held back waiting for acknowledgements (pyserial's handler leaves it on);
* a registered scheme (:mod:`rovlink.client.schemes`), such as ``sim://`` — a simulated
  controller in this process (``sim://?seed=1&leak_at=5&realtime=0&config=vehicle.toml``); its
  handler checks the URL here, before anything is opened.

Any other ``name://`` is a mistyped scheme, refused here (a ``ValueError`` naming it and the
schemes there are), not a port that failed to open.
"""

from __future__ import annotations

from dataclasses import dataclass
from urllib.parse import quote_plus, unquote_plus, urlencode

from rovlink.client.schemes import handler_module, load_handler, registered_schemes
from rovlink.protocol.text_enum import StrEnum

__all__ = ["DEFAULT_BAUDRATE", "Endpoint", "Scheme", "parse_url", "pyserial_schemes"]

DEFAULT_BAUDRATE = 115200
#: The fastest USB-serial bridges run at 12 Mbaud; beyond, pyserial overflows a C int.
MAX_BAUDRATE = 12_000_000


class Scheme(StrEnum):
    """How an endpoint is opened."""

    SERIAL = "serial"  # pyserial: a device path or a pyserial URL
    TCP = "tcp"  # socket://host:port, opened natively
    REGISTERED = "registered"  # a scheme of the registry (sim://), opened by its handler


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A parsed connection URL.

    ``target`` is what the opener needs: the pyserial URL or path without ``baudrate``,
    ``host:port`` for TCP, or the whole URL for a registered scheme (named by ``handler``).
    """

    url: str
    scheme: Scheme
    target: str
    baudrate: int = DEFAULT_BAUDRATE
    host: str = ""
    port: int = 0
    handler: str = ""

    @property
    def is_device(self) -> bool:
        """Whether the endpoint is a device path (a serial port or pseudo-terminal), not a URL.

        >>> parse_url("/dev/ttyUSB0").is_device, parse_url("socket://127.0.0.1:5760").is_device
        (True, False)
        """
        return self.scheme is Scheme.SERIAL and "://" not in self.target


def _split_query(url: str) -> tuple[str, list[tuple[str, str | None]]]:
    """The URL before ``?`` and its options, in order: ``(name, value)``, or ``(name, None)``
    for a flag such as rfc2217://'s ``ign_set_control`` or spy://'s ``raw``."""
    base, _, query = url.partition("?")
    pairs: list[tuple[str, str | None]] = []
    for field in query.split("&") if query else ():
        name, equals, value = field.partition("=")
        if not name:
            raise ValueError(f"{url!r}: malformed query {query!r}")
        pairs.append((unquote_plus(name), unquote_plus(value) if equals else None))
    return base, pairs


def _query_text(pairs: list[tuple[str, str | None]]) -> str:
    """Options as pyserial reads them (a flag stays a bare name)."""
    return "&".join(
        quote_plus(name) if value is None else urlencode([(name, value)]) for name, value in pairs
    )


def _parse_baudrate(url: str, text: str) -> int:
    if not text.isdigit() or not 0 < int(text) <= MAX_BAUDRATE:
        raise ValueError(f"{url!r}: baudrate must be an integer in 1–{MAX_BAUDRATE}, got {text!r}")
    return int(text)


def _parse_registered(url: str, scheme: str) -> Endpoint:
    try:
        load_handler(scheme).check_url(url)
    except ImportError as error:
        raise ValueError(f"{url!r}: {error}") from None
    return Endpoint(url, Scheme.REGISTERED, url, handler=scheme)


def _parse_tcp(url: str, base: str, baudrate: int) -> Endpoint:
    address = base[len("socket://") :].rstrip("/")
    host, colon, port_text = address.rpartition(":")
    if not colon or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"{url!r}: expected socket://HOST:PORT with a port in 1–65535")
    return Endpoint(url, Scheme.TCP, address, baudrate, host=host.strip("[]"), port=int(port_text))


def parse_url(url: str, baudrate: int | None = None) -> Endpoint:
    """Parse a connection URL; ``baudrate`` overrides nothing but must agree with ``?baudrate=``.

    >>> parse_url("/dev/ttyUSB0?baudrate=9600").baudrate
    9600
    >>> parse_url("socket://localhost:5760").port
    5760
    >>> parse_url("sim://?seed=1").handler
    'sim'
    """
    if not isinstance(url, str):
        raise TypeError(f"connection URL must be a non-empty string, got {url!r}")
    if not url.strip():
        raise ValueError(f"connection URL must be a non-empty string, got {url!r}")
    url = url.strip()
    # Checked for every scheme: a program written against sim:// (which has no baud rate) must
    # not find its bad value only when it moves to the robot's port.
    if baudrate is not None:
        baudrate_text = f"baudrate must be an integer in 1–{MAX_BAUDRATE}, got {baudrate!r}"
        if isinstance(baudrate, bool) or not isinstance(baudrate, int):
            raise TypeError(baudrate_text)
        if not 0 < baudrate <= MAX_BAUDRATE:
            raise ValueError(baudrate_text)
    scheme = url.partition(":")[0]
    if scheme != scheme.lower() and handler_module(scheme.lower()) is not None:
        # Before, SIM:// went to pyserial, which said "protocol 'sim' not known" of rovlink's
        # own scheme.
        raise ValueError(f"{url!r}: write the scheme in lower case: {scheme.lower()}://")
    if handler_module(scheme) is not None:
        return _parse_registered(url, scheme)
    base, pairs = _split_query(url)
    rest = [(name, value) for name, value in pairs if name != "baudrate"]
    from_url = [_parse_baudrate(url, value or "") for name, value in pairs if name == "baudrate"]
    if len(set(from_url)) > 1:
        raise ValueError(f"{url!r}: baudrate given twice with different values")
    if from_url and baudrate is not None and from_url[0] != baudrate:
        raise ValueError(
            f"{url!r}: baudrate={baudrate} disagrees with the URL's baudrate={from_url[0]}"
        )
    rate = from_url[0] if from_url else baudrate or DEFAULT_BAUDRATE
    if base.startswith("socket://") and not rest:
        return _parse_tcp(url, base, rate)
    if "://" not in base and rest:
        names = ", ".join(name for name, _ in rest)
        raise ValueError(f"{url!r}: a serial device takes only ?baudrate=, not {names}")
    if "://" in base:
        _check_pyserial_scheme(url, base)
    target = base + ("?" + _query_text(rest) if rest else "")
    return Endpoint(url, Scheme.SERIAL, target, rate)


def _check_pyserial_scheme(url: str, base: str) -> None:
    """ValueError naming the scheme of ``base`` (``name://…``), and the schemes there are, if
    pyserial has no handler for it: a mistyped scheme is said before anything is opened (it
    was a failure to open, in pyserial's words, "protocol 'nosuch' not known")."""
    scheme = base.partition("://")[0].lower()  # (pyserial reads schemes in any case)
    serial_schemes = pyserial_schemes()
    if scheme in serial_schemes:
        return
    known = ", ".join(f"{name}://" for name in sorted({*serial_schemes, *registered_schemes()}))
    tcp = f" (a TCP address is socket://{base.partition('://')[2]})" if scheme == "tcp" else ""
    raise ValueError(
        f"{url!r}: unknown URL scheme {scheme}:// (known: {known}; or a serial device's path, "
        f"such as /dev/ttyUSB0 or COM3){tcp}"
    )


def pyserial_schemes() -> frozenset[str]:
    """The URL schemes pyserial opens: a ``protocol_NAME`` module in one of its handler
    packages (``serial.protocol_handler_packages``, which a program may extend), as pyserial's
    ``serial_for_url`` looks them up.

    >>> {"loop", "socket", "rfc2217", "spy"} <= pyserial_schemes()
    True
    """
    import importlib  # noqa: PLC0415 - only for a URL with a scheme of pyserial's
    import pkgutil  # noqa: PLC0415

    import serial  # noqa: PLC0415 - pyserial is only needed when a serial port is opened

    names: set[str] = set()
    for package_name in serial.protocol_handler_packages:
        try:
            package = importlib.import_module(package_name)
        except ImportError:
            continue
        for module in pkgutil.iter_modules(getattr(package, "__path__", [])):
            if module.name.startswith("protocol_"):
                names.add(module.name.removeprefix("protocol_"))
    return frozenset(names)
