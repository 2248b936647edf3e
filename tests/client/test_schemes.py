"""URL schemes of other packages reach the client through its registry, never through imports."""

from __future__ import annotations

import re
import subprocess
import sys
import types

import pytest

import rovlink
from rovlink.client import schemes
from rovlink.client.errors import ConnectError
from rovlink.client.links import open_link
from rovlink.client.url import Scheme, parse_url


@pytest.mark.integration
def test_the_client_does_not_import_the_simulator() -> None:
    code = (
        "import sys, rovlink.client, rovlink.aio, rovlink.client.links\n"
        "loaded = sorted(m for m in sys.modules if m.startswith(('rovlink.sim', "
        "'rovlink.controller')))\n"
        "print(loaded)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"


def test_a_registered_scheme_is_checked_and_opened_by_its_handler(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    opened: list[str] = []
    handler = types.ModuleType("loopback_handler")

    def check_url(url: str) -> None:
        if "bad" in url:
            raise ValueError(f"{url!r}: bad option")

    def open_url(url: str) -> object:
        import serial

        opened.append(url)
        return serial.serial_for_url("loop://", timeout=0.05)

    handler.check_url = check_url  # type: ignore[attr-defined]
    handler.open_url = open_url  # type: ignore[attr-defined]
    handler.DESCRIPTION = "a loop for tests"  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "loopback_handler", handler)
    schemes.register_scheme("loopy", "loopback_handler")
    try:
        with pytest.raises(ValueError, match="bad option"):
            parse_url("loopy://bad")
        endpoint = parse_url("loopy://?x=1")
        assert endpoint.scheme is Scheme.REGISTERED
        link = open_link(endpoint)
        try:
            assert opened == ["loopy://?x=1"]
            assert link.description == "a loop for tests"
            link.write(b"#qd!")
            assert link.read_available(1.0) == b"#qd!"
        finally:
            link.close()
    finally:
        schemes.unregister_scheme("loopy")
    assert schemes.handler_module("loopy") is None


def test_a_scheme_whose_handler_cannot_be_imported_says_so() -> None:
    schemes.register_scheme("missing", "no_such_package.handler")
    try:
        with pytest.raises(ValueError, match=r"missing:// needs no_such_package\.handler"):
            parse_url("missing://x")
    finally:
        schemes.unregister_scheme("missing")


@pytest.mark.parametrize("name", ["socket", "loop", "Sim", "two words"])
def test_pyserial_schemes_and_bad_names_cannot_be_registered(name: str) -> None:
    with pytest.raises(ValueError, match="scheme"):
        schemes.register_scheme(name, "x")


def test_sim_opens_through_the_registry() -> None:
    with rovlink.connect("sim://?seed=1&realtime=0") as rov:
        assert rov.description == "simulated controller"
        assert 0 <= rov.depth_cm() <= 9999


def test_open_errors_name_the_port() -> None:
    with pytest.raises(ConnectError, match="not a serial port"):
        open_link(parse_url("/dev/null"))
    with pytest.raises(ConnectError, match="cannot open /dev/ttyNOSUCH9: No such file"):
        open_link(parse_url("/dev/ttyNOSUCH9"))


def test_the_example_of_register_scheme_leaves_rovlinks_own_schemes_alone() -> None:
    # (Before, it re-pointed fault:// to rovlink.fault.url, a module that does not exist: a
    # program that copied it could no longer open fault:// at all.)
    assert schemes.register_scheme.__doc__ is not None
    examples = re.findall(
        r'register_scheme\("(\w+)", "([\w.]+)"\)', schemes.register_scheme.__doc__
    )
    assert examples
    for scheme, module in examples:
        assert schemes.handler_module(scheme) is None, f"{scheme}:// is rovlink's own"
        assert not module.startswith("rovlink."), f"{module}: a handler of rovlink's own"
