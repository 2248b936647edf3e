"""The options every command that talks to a controller shares, defined once.

Used as annotations: ``checksum: ChecksumOption = False``.
"""

from __future__ import annotations

from typing import Annotated

import typer

from rovlink.protocol import ALGORITHMS

__all__ = [
    "DEFAULT_URL",
    "AlgorithmOption",
    "BaudrateOption",
    "ChecksumOption",
    "RetriesOption",
    "TimeoutOption",
    "UrlArgument",
    "check_algorithm",
]

DEFAULT_URL = "sim://"


def check_algorithm(name: str) -> str:
    """Refuse an unknown checksum algorithm name before anything is opened."""
    if name not in ALGORITHMS:
        raise typer.BadParameter(f"{name!r} is not one of {', '.join(sorted(ALGORITHMS))}")
    return name


UrlArgument = Annotated[
    str,
    typer.Argument(
        help="Serial device, pyserial URL (socket://host:port, …) or sim:// (the simulator)."
    ),
]
ChecksumOption = Annotated[bool, typer.Option("--checksum", help="Use checksum mode.")]
AlgorithmOption = Annotated[
    str,
    typer.Option(
        "--algorithm",
        help=f"Checksum algorithm: {', '.join(sorted(ALGORITHMS))}.",
        callback=check_algorithm,
    ),
]
BaudrateOption = Annotated[
    int | None, typer.Option("--baudrate", help="Serial speed, baud (default 115200).", min=1)
]
TimeoutOption = Annotated[
    float, typer.Option("--timeout", help="Seconds to wait for a reply, per attempt.", min=0.001)
]
RetriesOption = Annotated[int, typer.Option("--retries", help="Extra attempts of a query.", min=0)]
