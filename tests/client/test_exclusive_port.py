"""P22: a serial port has one host at a time; a second opener is told so at once."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator

import pytest

from rovlink.client import links
from rovlink.client.errors import ConnectError
from rovlink.client.links import SerialFdLink, open_link
from rovlink.client.url import parse_url
from tests.terminals import open_as_another_user

pytestmark = pytest.mark.integration


@pytest.fixture
def pty_path() -> Iterator[str]:
    controller_side, host_side = os.openpty()
    try:
        yield os.ttyname(host_side)
    finally:
        os.close(controller_side)
        os.close(host_side)


def test_a_second_opener_of_a_port_gets_a_clear_error(pty_path: str) -> None:
    first = open_link(parse_url(pty_path))
    try:
        with pytest.raises(ConnectError) as raised:
            open_link(parse_url(pty_path))
        # The same program: a client it did not close (a notebook's cell run again). Before,
        # it was told of another program, and looked for one.
        assert str(raised.value) == (
            f"{pty_path} is already open in this program: a client that was not closed? (close "
            "it first, or connect in a `with` block; a port has one host at a time)"
        )
    finally:
        first.close()
    # Released on close: the port opens again.
    open_link(parse_url(pty_path)).close()


def test_a_port_another_program_holds_is_said_to_be_open_in_another_program(
    pty_path: str,
) -> None:
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys, serial; port = serial.Serial(sys.argv[1], exclusive=True); print('open', "
            "flush=True); sys.stdin.read()",
            pty_path,
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None
        assert holder.stdout.readline() == "open\n"
        with pytest.raises(ConnectError) as raised:
            open_link(parse_url(pty_path))
        assert str(raised.value) == (
            f"{pty_path} is already open in another program (a port has one host at a time)"
        )
    finally:
        holder.kill()
        holder.wait()


def test_a_serial_device_is_closed_to_every_other_program_while_open(
    pty_path: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A pseudo-terminal stands in for a serial device (the tests have none): taken for one,
    # it gets the terminal's exclusive mode as a device does.
    monkeypatch.setattr(links, "_is_pseudo_terminal", lambda fd: False)
    os.chmod(pty_path, 0o666)  # any user may open it: only the exclusive mode keeps them out
    assert "opened" in open_as_another_user(pty_path)
    link = open_link(parse_url(pty_path))
    try:
        assert isinstance(link, SerialFdLink)
        assert link.exclusive_mode
        # A program that takes no lock (a shell, screen) is refused by the kernel.
        assert "busy" in open_as_another_user(pty_path).lower()
    finally:
        link.close()
    # The mode is cleared on close, although the port stays open elsewhere (the fixture's
    # descriptors): the next program opens it.
    assert "opened" in open_as_another_user(pty_path)


def test_a_pseudo_terminal_is_not_left_in_exclusive_mode(pty_path: str) -> None:
    # Its server keeps the other descriptors open, so the mode would outlive a host that
    # crashed; the lock still keeps out a second rovlink (the first test).
    link = open_link(parse_url(pty_path))
    try:
        assert isinstance(link, SerialFdLink)
        assert not link.exclusive_mode
        os.chmod(pty_path, 0o666)
        assert "opened" in open_as_another_user(pty_path)
    finally:
        link.close()
