"""The ``sim://`` URL: a simulated controller in this process, for the host driver and the tools.

The client finds this module through its registry of URL schemes
(:mod:`rovlink.client.schemes`), so the host driver never imports the simulator.
The simulator's options are query parameters: ``sim://?seed=1&leak_at=5&realtime=0&config=f.toml``.

>>> parse_sim_url("sim://?leak_at=5&seed=1")
SimOptions(seed=1, leak_at_s=5.0, config=None, realtime=True, preset=None, algorithm=None)
>>> parse_sim_url("sim://?seed=x")
Traceback (most recent call last):
...
ValueError: 'sim://?seed=x': seed must be an integer, got 'x'
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from urllib.parse import parse_qsl

from rovlink.sim.port import SimulatedPort, open_port

__all__ = [
    "DESCRIPTION",
    "SIM_OPTIONS",
    "SimOptions",
    "check_url",
    "open_url",
    "parse_sim_url",
    "with_algorithm",
]

#: What the client calls a link opened here.
DESCRIPTION = "simulated controller"

#: ``sim://`` query parameters and what they mean.
SIM_OPTIONS: dict[str, str] = {
    "seed": "integer seed of the simulator's noise",
    "leak_at": "seconds after start when the leak sensor fires",
    "config": "path of a vehicle/controller configuration file (TOML)",
    "realtime": "1 (default) to run in real time, 0 as fast as possible",
    "preset": "a vehicle preset: light, standard or heavy (see rovlink.sim.presets)",
    "algorithm": "the controller's checksum algorithm: crc8, sum8 or xor (default: the "
    "config file's checksum_algorithm, else crc8)",
}

_FLAGS = {"1": True, "true": True, "yes": True, "0": False, "false": False, "no": False}


@dataclass(frozen=True)
class SimOptions:
    """The simulator's options from a ``sim://`` URL (keywords of :func:`open_port`)."""

    seed: int | None = None
    leak_at_s: float | None = None
    config: str | None = None
    realtime: bool = True
    preset: str | None = None
    algorithm: str | None = None


def parse_sim_url(url: str) -> SimOptions:
    """The options of a ``sim://`` URL; ValueError naming the URL and what is wrong."""
    base, _, query = url.partition("?")
    if base not in ("sim://", "sim:"):
        raise ValueError(f"{url!r}: sim:// takes no host or path, only ?options")
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise ValueError(f"{url!r}: malformed query {query!r}") from None
    values = dict(pairs)
    # dict() keeps the last of a repeated option: `seed=1&leak_at=5&seed=2` ran with seed 2 and
    # said nothing of the 1.
    for name, value in pairs:
        if values[name] != value:
            raise ValueError(f"{url!r}: sim option {name!r} given twice with different values")
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
        if not 0 <= leak_at_s < math.inf:
            raise ValueError(
                f"{url!r}: leak_at must be a non-negative number of seconds, got {text!r}"
            )
        options = replace(options, leak_at_s=leak_at_s)
    if "realtime" in values:
        flag = _FLAGS.get(values["realtime"].lower())
        if flag is None:
            raise ValueError(f"{url!r}: realtime must be 1 or 0, got {values['realtime']!r}")
        options = replace(options, realtime=flag)
    if "preset" in values:
        from rovlink.sim.presets import PRESETS  # noqa: PLC0415 - only for this option

        if values["preset"] not in PRESETS:
            known = ", ".join(sorted(PRESETS))
            raise ValueError(f"{url!r}: unknown preset {values['preset']!r}; known: {known}")
        options = replace(options, preset=values["preset"])
    if "algorithm" in values:
        from rovlink.protocol import ALGORITHMS  # noqa: PLC0415 - only for this option

        if values["algorithm"] not in ALGORITHMS:
            known = ", ".join(sorted(ALGORITHMS))
            raise ValueError(
                f"{url!r}: unknown checksum algorithm {values['algorithm']!r}; known: {known}"
            )
        options = replace(options, algorithm=values["algorithm"])
    if "config" in values:
        if not values["config"]:
            raise ValueError(f"{url!r}: config needs a file path")
        options = replace(options, config=values["config"])
    return options


def check_url(url: str) -> None:
    """Raise ValueError if ``url`` is not a valid ``sim://`` URL (the registry's check).

    >>> check_url("sim://?seed=1")
    """
    parse_sim_url(url)


def open_url(url: str) -> SimulatedPort:
    """Start a simulated controller for ``url`` and return its port (the registry's opener).

    Example::

        port = open_url("sim://?seed=1&realtime=0")
    """
    options = parse_sim_url(url)
    return open_port(
        seed=options.seed,
        leak_at_s=options.leak_at_s,
        config=options.config,
        realtime=options.realtime,
        preset=options.preset,
        algorithm=options.algorithm,
    )


def with_algorithm(url: str, algorithm: str) -> str:
    """``url`` whose simulated controller uses the checksum ``algorithm``: the host's, so that
    the two agree. ValueError if the URL already names another one.

    >>> with_algorithm("sim://?seed=1", "xor")
    'sim://?seed=1&algorithm=xor'
    >>> with_algorithm("sim://?algorithm=xor", "xor")
    'sim://?algorithm=xor'
    >>> with_algorithm("sim://?algorithm=sum8", "xor")
    Traceback (most recent call last):
    ...
    ValueError: 'sim://?algorithm=sum8': the simulated controller's algorithm is sum8, not xor
    """
    named = parse_sim_url(url).algorithm
    if named == algorithm:
        return url
    if named is not None:
        raise ValueError(
            f"{url!r}: the simulated controller's algorithm is {named}, not {algorithm}"
        )
    base, _, query = url.partition("?")
    return f"{base}?{query}&algorithm={algorithm}" if query else f"{base}?algorithm={algorithm}"
