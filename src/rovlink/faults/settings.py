"""What a fault-injecting link does to the bytes, read from a ``fault://`` URL.

``fault://?inner=URL&ber=1e-3&drop=0.01&dup=0.005&delay_ms=5&jitter_ms=2&seed=1``

* ``inner`` — the link underneath, any URL the driver opens (percent-encode its own ``?``/``&``:
  ``inner=sim%3A%2F%2F%3Fseed%3D1%26realtime%3D0``);
* ``ber`` — probability that each bit is flipped;
* ``drop`` / ``dup`` — probability that each byte is lost / sent twice;
* ``delay_ms`` / ``jitter_ms`` — every chunk arrives this late, give or take up to the jitter
  (uniform), never before the chunk ahead of it: a serial line does not reorder;
* ``seed`` — the random stream, so that a failure reproduces.

Every fault applies to both directions, each with its own random stream.

>>> inner, settings = parse_fault_url("fault://?inner=sim://&ber=1e-3&seed=7")
>>> inner, settings.ber, settings.seed
('sim://', 0.001, 7)
>>> parse_fault_url("fault://?ber=1e-3")
Traceback (most recent call last):
...
ValueError: 'fault://?ber=1e-3': inner=URL is required (the link to inject faults into)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from urllib.parse import parse_qsl, quote

__all__ = ["FAULT_OPTIONS", "FaultSettings", "fault_url", "parse_fault_url"]

#: ``fault://`` query parameters and what they mean.
FAULT_OPTIONS: dict[str, str] = {
    "inner": "the link underneath (a URL the driver opens; percent-encode its ? and &)",
    "ber": "bit error rate: probability that each bit is flipped (0–0.5)",
    "drop": "probability that each byte is lost (0–1)",
    "dup": "probability that each byte is sent twice (0–1)",
    "delay_ms": "delay of every chunk, ms (0–10000)",
    "jitter_ms": "random extra or less delay, up to this, ms (0–delay_ms)",
    "seed": "integer seed of the random faults (default 0)",
}

_MAX_DELAY_MS = 10_000.0


@dataclass(frozen=True)
class FaultSettings:
    """The faults of one link (both directions)."""

    ber: float = 0.0
    drop: float = 0.0
    dup: float = 0.0
    delay_ms: float = 0.0
    jitter_ms: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        for name, maximum in (("ber", 0.5), ("drop", 1.0), ("dup", 1.0)):
            _check_range(name, getattr(self, name), 0.0, maximum)
        _check_range("delay_ms", self.delay_ms, 0.0, _MAX_DELAY_MS)
        _check_range("jitter_ms", self.jitter_ms, 0.0, self.delay_ms)

    @property
    def delays(self) -> bool:
        """Whether chunks are held back at all."""
        return self.delay_ms > 0.0


def _check_range(name: str, value: float, minimum: float, maximum: float) -> None:
    if not (math.isfinite(value) and minimum <= value <= maximum):
        raise ValueError(f"{name} must be in {minimum:g}–{maximum:g}, got {value!r}")


def parse_fault_url(url: str) -> tuple[str, FaultSettings]:
    """The inner URL and the settings of a ``fault://`` URL; ValueError naming what is wrong."""
    base, _, query = url.partition("?")
    if base not in ("fault://", "fault:"):
        raise ValueError(f"{url!r}: fault:// takes no host or path, only ?options")
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise ValueError(f"{url!r}: malformed query {query!r}") from None
    values: dict[str, str] = {}
    for name, value in pairs:
        if name not in FAULT_OPTIONS:
            known = ", ".join(FAULT_OPTIONS)
            raise ValueError(
                f"{url!r}: unknown fault option {name!r} (known: {known}); if it belongs to the "
                "inner URL, percent-encode that URL's ? and & (%3F, %26)"
            )
        if name in values:
            raise ValueError(f"{url!r}: {name} is given twice")
        values[name] = value
    inner = values.pop("inner", "")
    if not inner:
        raise ValueError(f"{url!r}: inner=URL is required (the link to inject faults into)")
    numbers: dict[str, float | int] = {}
    for name, text in values.items():
        try:
            numbers[name] = int(text) if name == "seed" else float(text)
        except ValueError:
            kind = "an integer" if name == "seed" else "a number"
            raise ValueError(f"{url!r}: {name} must be {kind}, got {text!r}") from None
    try:
        settings = FaultSettings(**numbers)  # type: ignore[arg-type]
    except ValueError as error:
        raise ValueError(f"{url!r}: {error}") from None
    return inner, settings


def fault_url(inner: str, settings: FaultSettings) -> str:
    """The ``fault://`` URL for ``inner`` with ``settings`` (the inverse of the parser).

    >>> fault_url("sim://?seed=1&realtime=0", FaultSettings(ber=1e-3, seed=2))
    'fault://?inner=sim%3A%2F%2F%3Fseed%3D1%26realtime%3D0&ber=0.001&seed=2'
    """
    parts = [f"inner={quote(inner, safe='')}"]
    defaults = FaultSettings()
    for name in ("ber", "drop", "dup", "delay_ms", "jitter_ms", "seed"):
        value = getattr(settings, name)
        if value != getattr(defaults, name):
            # repr: the shortest text that reads back as the same float (``g`` kept 6 digits,
            # so a URL logged to reproduce a run described other faults).
            parts.append(f"{name}={value!r}")
    return "fault://?" + "&".join(parts)
