"""P22: a serial port has one host at a time; a second opener is told so at once."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from rovlink.client.errors import ConnectError
from rovlink.client.links import open_link
from rovlink.client.url import parse_url

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
        assert str(raised.value) == (
            f"{pty_path} is already open in another program (a port has one host at a time)"
        )
    finally:
        first.close()
    # Released on close: the port opens again.
    open_link(parse_url(pty_path)).close()
