"""Connection URLs: what ``rovlink.connect`` opens, parsed and checked before anything is opened.

* a serial device path (``/dev/ttyUSB0``, ``COM3``, a pseudo-terminal's path) or any pyserial URL
  (``loop://``, ``rfc2217://host:port``, ``spy://…``), with ``?baudrate=N`` (default 115200);
* ``socket://host:port`` — TCP, opened natively with Nagle's algorithm off, so small frames are
  not held back waiting for acknowledgements (pyserial's handler leaves it on);
* ``sim://`` — a simulated controller in this process; the simulator's options are query
  parameters: ``sim://?seed=1&leak_at=5&realtime=0&config=vehicle.toml``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from urllib.parse import parse_qsl, urlencode

from rovlink.protocol.text_enum import StrEnum

__all__ = ["DEFAULT_BAUDRATE", "SIM_OPTIONS", "Endpoint", "Scheme", "SimOptions", "parse_url"]

DEFAULT_BAUDRATE = 115200


class Scheme(StrEnum):
    """How an endpoint is opened."""

    SERIAL = "serial"  # pyserial: a device path or a pyserial URL
    TCP = "tcp"  # socket://host:port, opened natively
    SIM = "sim"  # the in-process simulated controller


#: ``sim://`` query parameters and what they mean.
SIM_OPTIONS: dict[str, str] = {
    "seed": "integer seed of the simulator's noise",
    "leak_at": "seconds after start when the leak sensor fires",
    "config": "path of a vehicle/controller configuration file (TOML)",
    "realtime": "1 (default) to run in real time, 0 as fast as possible",
}


@dataclass(frozen=True, slots=True)
class SimOptions:
    """The simulator's options from a ``sim://`` URL (keywords of ``rovlink.sim.open_port``)."""

    seed: int | None = None
    leak_at_s: float | None = None
    config: str | None = None
    realtime: bool = True


@dataclass(frozen=True, slots=True)
class Endpoint:
    """A parsed connection URL.

    ``target`` is what the opener needs: the pyserial URL or path without ``baudrate``, or
    ``host:port`` for TCP.
    """

    url: str
    scheme: Scheme
    target: str
    baudrate: int = DEFAULT_BAUDRATE
    sim_options: SimOptions = field(default_factory=SimOptions)
    host: str = ""
    port: int = 0


def _split_query(url: str) -> tuple[str, list[tuple[str, str]]]:
    base, _, query = url.partition("?")
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise ValueError(f"{url!r}: malformed query {query!r}") from None
    return base, pairs


def _parse_baudrate(url: str, text: str) -> int:
    if not text.isdigit() or int(text) <= 0:
        raise ValueError(f"{url!r}: baudrate must be a positive integer, got {text!r}")
    return int(text)


_FLAGS = {"1": True, "true": True, "yes": True, "0": False, "false": False, "no": False}


def _parse_sim(url: str, base: str, pairs: list[tuple[str, str]]) -> Endpoint:
    if base not in ("sim://", "sim:"):
        raise ValueError(f"{url!r}: sim:// takes no host or path, only ?options")
    values = dict(pairs)
    unknown = [name for name in values if name not in SIM_OPTIONS]
    if unknown:
        known = ", ".join(SIM_OPTIONS)
        raise ValueError(f"{url!r}: unknown sim option {unknown[0]!r}; known options: {known}")
    options = SimOptions()
    if "seed" in values:
        try:
            options = replace(options, seed=int(values["seed"]))
        except ValueError:
            raise ValueError(f"{url!r}: seed must be an integer, got {values['seed']!r}") from None
    if "leak_at" in values:
        text = values["leak_at"]
        try:
            leak_at_s = float(text)
        except ValueError:
            leak_at_s = -1.0
        if not leak_at_s >= 0:
            raise ValueError(
                f"{url!r}: leak_at must be a non-negative number of seconds, got {text!r}"
            )
        options = replace(options, leak_at_s=leak_at_s)
    if "realtime" in values:
        flag = _FLAGS.get(values["realtime"].lower())
        if flag is None:
            raise ValueError(f"{url!r}: realtime must be 1 or 0, got {values['realtime']!r}")
        options = replace(options, realtime=flag)
    if "config" in values:
        if not values["config"]:
            raise ValueError(f"{url!r}: config needs a file path")
        options = replace(options, config=values["config"])
    return Endpoint(url, Scheme.SIM, "sim://", sim_options=options)


def _parse_tcp(url: str, base: str, baudrate: int) -> Endpoint:
    address = base[len("socket://"):].rstrip("/")
    host, colon, port_text = address.rpartition(":")
    if not colon or not host or not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise ValueError(f"{url!r}: expected socket://HOST:PORT with a port in 1–65535")
    return Endpoint(url, Scheme.TCP, address, baudrate, host=host.strip("[]"),
                    port=int(port_text))


def parse_url(url: str, baudrate: int | None = None) -> Endpoint:
    """Parse a connection URL; ``baudrate`` overrides nothing but must agree with ``?baudrate=``.

    >>> parse_url("/dev/ttyUSB0?baudrate=9600").baudrate
    9600
    >>> parse_url("socket://localhost:5760").port
    5760
    >>> parse_url("sim://?leak_at=5&seed=1").sim_options
    SimOptions(seed=1, leak_at_s=5.0, config=None, realtime=True)
    """
    if not isinstance(url, str) or not url.strip():
        raise ValueError(f"connection URL must be a non-empty string, got {url!r}")
    url = url.strip()
    base, pairs = _split_query(url)
    if base.startswith("sim:"):
        return _parse_sim(url, base, pairs)
    rest = [(name, value) for name, value in pairs if name != "baudrate"]
    from_url = [_parse_baudrate(url, value) for name, value in pairs if name == "baudrate"]
    if len(set(from_url)) > 1:
        raise ValueError(f"{url!r}: baudrate given twice with different values")
    if baudrate is not None and (isinstance(baudrate, bool) or not isinstance(baudrate, int)
                                 or baudrate <= 0):
        raise ValueError(f"baudrate must be a positive integer, got {baudrate!r}")
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
    target = base + ("?" + urlencode(rest) if rest else "")
    return Endpoint(url, Scheme.SERIAL, target, rate)
