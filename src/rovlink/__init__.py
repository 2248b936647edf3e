"""rovlink: drive an underwater robot's low-level controller over its serial command protocol.

The protocol core is :mod:`rovlink.protocol`; the host driver is ``rovlink.connect`` (blocking)
and ``rovlink.aio.connect`` (asyncio); the controller and the simulated robot are
:mod:`rovlink.controller` and :mod:`rovlink.sim`.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
