"""A TCP port already taken is reported with the address the command could not listen on."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from rovlink.cli import main

pytestmark = pytest.mark.integration


@pytest.fixture
def taken_port() -> Iterator[int]:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        yield int(taken.getsockname()[1])


def test_rovlink_controller_names_the_busy_address(
    taken_port: int, capsys: pytest.CaptureFixture[str]
) -> None:
    # Before, "cannot listen on 5760" when the port was given alone: not which address.
    assert main(["controller", "--board", "sim", "--tcp", str(taken_port)]) == 1
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert error == (
        f"rovlink controller: cannot listen on 127.0.0.1:{taken_port}: Address already in use"
    )


def test_rovlink_fault_names_the_busy_address(
    taken_port: int, capsys: pytest.CaptureFixture[str]
) -> None:
    # Before, the URL as typed ("socket://127.0.0.1:PORT"), not the address as the others say it.
    argv = ["fault", "--listen", f"socket://127.0.0.1:{taken_port}", "--to", "sim://"]
    assert main(argv) == 1
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert (
        error == f"rovlink fault: cannot listen on 127.0.0.1:{taken_port}: Address already in use"
    )
