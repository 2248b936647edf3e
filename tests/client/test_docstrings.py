"""House rule: every public function and method of the host driver has a docstring with an example.

The public driver is what ``rovlink``, ``rovlink.client`` and ``rovlink.aio`` export, what the
driver's link, port-closing, stop-at-exit, transport, stray-event, URL, URL-scheme,
reconnection, in-flight-slot and wake-up modules export (the command line and the tools use
them), with the methods and
properties of the classes among them (inherited ones included), and the public functions of
``rovlink send`` and ``rovlink demo``.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator
from types import ModuleType

import rovlink
import rovlink.aio
import rovlink.aio.slots
import rovlink.aio.transport
import rovlink.aio.wakeup
import rovlink.cli.demo
import rovlink.cli.send
import rovlink.client
import rovlink.client.links
import rovlink.client.port_closing
import rovlink.client.reconnection
import rovlink.client.schemes
import rovlink.client.stop_at_exit
import rovlink.client.unsolicited
import rovlink.client.url

MODULES: tuple[ModuleType, ...] = (
    rovlink,
    rovlink.client,
    rovlink.aio,
    rovlink.aio.slots,
    rovlink.aio.wakeup,
    rovlink.client.reconnection,
    rovlink.client.schemes,
    rovlink.client.url,
    rovlink.client.links,
    rovlink.client.port_closing,
    rovlink.client.stop_at_exit,
    rovlink.client.unsolicited,
    rovlink.aio.transport,
    rovlink.cli.send,
    rovlink.cli.demo,
)


def _members(cls: type) -> dict[str, object]:
    """The class's attributes, with those it inherits from rovlink's own classes."""
    members: dict[str, object] = {}
    for klass in cls.__mro__:
        if klass.__module__.startswith("rovlink."):
            for name, member in vars(klass).items():
                members.setdefault(name, member)  # the most derived definition wins
    return members


def _public_functions() -> Iterator[tuple[str, object]]:
    exported = [
        (f"{module.__name__}.{name}", getattr(module, name))
        for module in MODULES
        for name in module.__all__
        if name != "register"  # the command line's plumbing
    ]
    for name, value in exported:
        if inspect.isfunction(value):
            yield name, value
        elif inspect.isclass(value) and not issubclass(value, BaseException):
            for member_name, member in _members(value).items():
                function = member.fget if isinstance(member, property) else member
                if not inspect.isfunction(function):
                    continue
                # Public members, and a constructor that documents itself.
                if not member_name.startswith("_") or (
                    member_name == "__init__" and function.__doc__ is not None
                ):
                    yield f"{name}.{member_name}", function


def test_the_public_api_is_found() -> None:
    names = {name for name, _ in _public_functions()}
    assert {
        "rovlink.client.connect",
        "rovlink.aio.connect",
        "rovlink.client.Client.sensors",
        "rovlink.aio.AsyncClient.telemetry",
        "rovlink.client.Client.counters",
        "rovlink.client.links.PortLink.read_available",
        "rovlink.client.links.PortLink.port",
        "rovlink.client.links.SocketLink.read_available",  # inherited from FdLink
        "rovlink.client.links.SocketLink.recv_some",
        "rovlink.client.links.open_link",
        "rovlink.aio.transport.ByteTransport.write",
        "rovlink.aio.transport.transport_for",
        "rovlink.client.unsolicited.DropLog.report",
        "rovlink.client.unsolicited.deliver",
    } <= names


def test_every_public_function_has_an_example() -> None:
    missing = [
        name
        for name, function in _public_functions()
        if not any(marker in (inspect.getdoc(function) or "") for marker in ("Example", ">>>"))
    ]
    assert missing == []
