"""The ``fault://`` URL: any other link with seeded bit errors, losses, duplicates and delays.

The client finds this module through its registry of URL schemes, as it finds ``sim://``;
see :mod:`rovlink.faults.settings` for the options.

Example::

    import rovlink
    rov = rovlink.connect("fault://?inner=sim://&ber=1e-3&seed=1", checksum=True)
"""

from __future__ import annotations

from rovlink.client.errors import ConnectError
from rovlink.client.links import open_link
from rovlink.client.url import parse_url
from rovlink.faults.port import FaultPort
from rovlink.faults.settings import parse_fault_url

__all__ = ["DESCRIPTION", "check_url", "open_url"]

#: What the client calls a link opened here.
DESCRIPTION = "fault-injecting link"


def check_url(url: str) -> None:
    """Raise ValueError if ``url`` is not a valid ``fault://`` URL (its inner URL included).

    >>> check_url("fault://?inner=sim://&drop=0.01")
    """
    inner, _ = parse_fault_url(url)
    try:
        parse_url(inner)
    except ValueError as error:
        raise ValueError(f"{url!r}: inner URL: {error}") from None


def open_url(url: str) -> FaultPort:
    """Open the inner link and wrap it (the registry's opener)."""
    inner, settings = parse_fault_url(url)
    try:
        link = open_link(parse_url(inner))
    except ConnectError as error:
        raise OSError(f"inner link: {error}") from error
    return FaultPort(link, settings, name=f"fault:// over {link.description}")
