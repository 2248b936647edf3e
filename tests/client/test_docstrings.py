"""House rule: every public function and method of the host driver has a docstring with an example.

The public driver is what ``rovlink.client`` and ``rovlink.aio`` export, with the methods and
properties of the classes among them, and the public functions of ``rovlink send`` and
``rovlink demo``.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator

import rovlink.aio
import rovlink.cli.demo
import rovlink.cli.send
import rovlink.client


def _public_functions() -> Iterator[tuple[str, object]]:
    exported = [
        (f"{package.__name__}.{name}", getattr(package, name))
        for package in (rovlink.client, rovlink.aio, rovlink.cli.send, rovlink.cli.demo)
        for name in package.__all__
        if name != "register"  # the command line's plumbing
    ]
    for name, value in exported:
        if inspect.isfunction(value):
            yield name, value
        elif inspect.isclass(value) and not issubclass(value, BaseException):
            for member_name, member in vars(value).items():
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
    assert {"rovlink.client.connect", "rovlink.aio.connect", "rovlink.client.Client.sensors",
            "rovlink.aio.AsyncClient.telemetry", "rovlink.client.Client.counters"} <= names


def test_every_public_function_has_an_example() -> None:
    missing = [
        name for name, function in _public_functions()
        if not any(marker in (inspect.getdoc(function) or "") for marker in ("Example", ">>>"))
    ]
    assert missing == []
