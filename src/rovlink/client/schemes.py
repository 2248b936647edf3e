"""URL schemes opened by another package, found by name: how ``sim://`` reaches the client.

As pyserial finds its ``socket://`` and ``loop://`` handlers by module name, the client keeps a
registry that maps a scheme to the dotted path of a handler module and imports it only when such
a URL is used. The client therefore never imports the simulator (or any other provider): the
simulator stands beside the host driver, not under it.

A handler module offers two functions:

* ``check_url(url: str) -> None`` — raise :class:`ValueError` naming what is wrong with ``url``;
* ``open_url(url: str) -> port`` — a pyserial-like port (``read``, ``in_waiting``, ``write``,
  ``close``, ``timeout``, ``is_open``); :class:`OSError` or :class:`ValueError` if it cannot open;

and may name what it opens in ``DESCRIPTION`` (for messages and logs).

>>> handler_module("sim")
'rovlink.sim.url'
>>> register_scheme("example", "example_package.rovlink_url")
>>> handler_module("example")
'example_package.rovlink_url'
>>> unregister_scheme("example")
"""

from __future__ import annotations

import importlib
from types import ModuleType

__all__ = [
    "handler_module",
    "load_handler",
    "register_scheme",
    "registered_schemes",
    "unregister_scheme",
]

_HANDLERS: dict[str, str] = {
    "sim": "rovlink.sim.url",
    "fault": "rovlink.faults.url",
}


def register_scheme(scheme: str, module: str) -> None:
    """Open ``scheme://…`` URLs with the handler module named ``module`` (a dotted path).

    Example::

        register_scheme("myrov", "myteam.rov_url")   # then rovlink.connect("myrov://...")
    """
    if not scheme.isidentifier() or scheme != scheme.lower():
        raise ValueError(f"a URL scheme must be a lower-case name, got {scheme!r}")
    if scheme in ("socket", "loop", "rfc2217", "spy", "hwgrep", "alt", "cp2110"):
        raise ValueError(f"{scheme}:// is a pyserial scheme; it cannot be registered again")
    _HANDLERS[scheme] = module


def unregister_scheme(scheme: str) -> None:
    """Forget a registered scheme (no error if it was not registered).

    Example::

        unregister_scheme("myrov")
    """
    _HANDLERS.pop(scheme, None)


def registered_schemes() -> tuple[str, ...]:
    """The registered scheme names, sorted.

    >>> "sim" in registered_schemes()
    True
    """
    return tuple(sorted(_HANDLERS))


def handler_module(scheme: str) -> str | None:
    """The dotted path of ``scheme``'s handler module, or None if it is not registered.

    >>> handler_module("sim"), handler_module("ftp")
    ('rovlink.sim.url', None)
    """
    return _HANDLERS.get(scheme)


def load_handler(scheme: str) -> ModuleType:
    """Import ``scheme``'s handler module; ImportError naming the scheme if it cannot be.

    Example::

        load_handler("sim").check_url("sim://?seed=1")
    """
    module = _HANDLERS.get(scheme)
    if module is None:
        raise ImportError(f"no handler is registered for {scheme}://")
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise ImportError(
            f"{scheme}:// needs {module}, which cannot be imported: {error}"
        ) from error
