"""rovlink: drive an underwater robot's low-level controller over its serial command protocol.

The protocol core is :mod:`rovlink.protocol`; the host driver is ``rovlink.connect`` (blocking)
and ``rovlink.aio.connect`` (asyncio); the controller and the simulated robot are
:mod:`rovlink.controller` and :mod:`rovlink.sim`.

Example::

    import rovlink

    with rovlink.connect("sim://") as rov:
        print(rov.depth_cm())
"""

from __future__ import annotations

import importlib

# Not typing's: importing typing costs more than the rest of ``rovlink --version`` together.
TYPE_CHECKING = False

__version__ = "0.1.0"

__all__ = ["Sensors", "__version__", "connect"]

if TYPE_CHECKING:
    from typing import Any

    from rovlink.client import Sensors, connect

# The driver (and with it pyserial) loads on first use, so that ``import rovlink.protocol``
# stays dependency-free, as on a small board.
_LAZY = {"connect": "rovlink.client", "Sensors": "rovlink.client"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'rovlink' has no attribute {name!r}")
