"""``keptsim://``: the in-process simulator, keeping each port it opens for the test to inspect.

An example opens and closes its own client from a URL, as a user's program does; the test gives
it a ``keptsim://?…`` URL (the same options as ``sim://``) and reads the simulated controller's
state afterwards through :data:`OPENED`. Registered with ``rovlink.client.register_scheme``.
"""

from __future__ import annotations

from rovlink.sim.port import SimulatedPort
from rovlink.sim.url import check_url as check_sim_url
from rovlink.sim.url import open_url as open_sim_url

#: Every port opened, in order.
OPENED: list[SimulatedPort] = []

DESCRIPTION = "simulated controller"

SCHEME = "keptsim"


def _as_sim_url(url: str) -> str:
    return "sim" + url.removeprefix(SCHEME)


def check_url(url: str) -> None:
    """Raise ValueError if ``url`` is not a valid ``sim://`` URL under this scheme's name."""
    check_sim_url(_as_sim_url(url))


def open_url(url: str) -> SimulatedPort:
    """Open the simulator as ``sim://`` would, and keep the port."""
    port = open_sim_url(_as_sim_url(url))
    OPENED.append(port)
    return port
