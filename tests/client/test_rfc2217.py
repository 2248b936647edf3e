"""``rfc2217://`` against a real RFC 2217 server (Debian's ser2net) serving a controller's
serial port, here a pseudo-terminal with a fake controller behind it: both clients query it and
stop it, with the option pyserial needs for a server that does not acknowledge modem control."""

from __future__ import annotations

import asyncio
import os
import shutil
import socket
import subprocess
import tty
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
from serial import SerialException

import rovlink
import rovlink.aio
from rovlink.client import ConnectionLostError, links
from rovlink.client.links import _open_error
from rovlink.client.url import parse_url
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    ThreadCall,
    longest_loop_stall_s,
    wait_until,
)
from tests.client.fake_controller import FakeController

SER2NET = shutil.which("ser2net") or (
    "/usr/sbin/ser2net" if Path("/usr/sbin/ser2net").exists() else None
)
#: How soon a write given up must end: half the port's own timeout, 5 s, which is what it waited
#: for (ending at once, it has room for a loaded machine).
_PROMPT_S = 2.5


@dataclass
class Served:
    """A fake controller on a pseudo-terminal, served by ser2net at ``url``."""

    fake: FakeController
    url: str


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    if SER2NET is None:
        pytest.skip("ser2net is not installed (.ci/debian-packages)")
    controller_end, terminal = os.openpty()
    tty.setraw(terminal)
    fake = FakeController(controller_end)
    port = _free_port()
    config = tmp_path / "ser2net.yaml"
    config.write_text(
        "%YAML 1.1\n---\n"
        "connection: &rov\n"
        f"  accepter: telnet(rfc2217),tcp,127.0.0.1,{port}\n"
        f"  connector: serialdev,{os.ttyname(terminal)},115200n81,local\n"
    )
    server = subprocess.Popen(
        [SER2NET, "-n", "-d", "-c", str(config), "-P", str(tmp_path / "ser2net.pid")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )

    def listening() -> bool:
        try:
            socket.create_connection(("127.0.0.1", port), 0.2).close()
        except OSError:
            return False
        return True

    try:
        assert wait_until(listening), "ser2net did not listen"
        yield Served(fake, f"rfc2217://127.0.0.1:{port}?ign_set_control")
    finally:
        server.terminate()
        server.wait(CONDITION_TIMEOUT_S)
        fake.close()
        os.close(terminal)


def _stopped(fake: FakeController) -> bool:
    return "#stop!" in fake.frames()


@pytest.mark.integration
def test_the_blocking_client_queries_and_stops_a_controller_behind_ser2net(served: Served) -> None:
    # Before, every rfc2217:// URL failed to open with pyserial's NotImplementedError (the
    # client asked for a write timeout), and ?ign_set_control was refused as a malformed query.
    with rovlink.connect(served.url, keepalive=None) as rov:
        assert rov.depth_cm() == 123
        assert rov.sensors().heading_deg == 275
        rov.stop()
        assert served.fake.wait_for(_stopped, CONDITION_TIMEOUT_S)


@pytest.mark.integration
async def test_the_asyncio_client_queries_and_stops_a_controller_behind_ser2net(
    served: Served,
) -> None:
    async with rovlink.aio.connect(served.url, keepalive=None) as rov:
        assert await rov.depth_cm() == 123
        await rov.stop()
        assert await asyncio.to_thread(served.fake.wait_for, _stopped, CONDITION_TIMEOUT_S)


def test_a_server_that_does_not_acknowledge_modem_control_is_named_with_the_option() -> None:
    # pyserial waits 3 s for an acknowledgement ser2net does not send on a port without modem
    # lines, then says only "timeout while waiting for option 'control'".
    endpoint = parse_url("rfc2217://robot:2217")
    message = _open_error(endpoint, SerialException("timeout while waiting for option 'control'"))
    assert message.startswith("cannot open rfc2217://robot:2217: ")
    assert "?ign_set_control" in message


@pytest.mark.integration
@pytest.mark.realtime
async def test_closing_the_asyncio_client_does_not_stall_its_event_loop(served: Served) -> None:
    # pyserial's rfc2217:// close waits for its reader thread, then sleeps 0.3 s; done in the
    # event loop's thread, it held everything else up for as long (a bridge's heartbeats).
    rov = await rovlink.aio.connect(served.url, keepalive=None)
    assert await rov.depth_cm() == 123
    stall_s = await longest_loop_stall_s(rov.close)
    assert stall_s < 0.2, f"the event loop stood still for {stall_s:.2f} s"


@pytest.mark.integration
def test_a_write_waiting_on_an_rfc2217_port_is_given_up_at_once(served: Served) -> None:
    # pyserial's rfc2217:// cannot cancel a write: one that a controller no longer reading
    # held (ser2net stops taking bytes once the serial line is full) waited for the port's
    # socket timeout, 5 s, and a reconnection or close() waited with it. Giving the writes up
    # closes such a port (in a thread of its own), which ends the write at once.
    link = links.open_link(parse_url(served.url))
    try:
        assert isinstance(link, links.PortLink)
        served.fake.stop_reading()
        writer = ThreadCall(lambda: link.write(b"\r\n" * (1 << 23)))  # more than the line holds
        assert not writer.done.wait(0.3), f"the write ended at once: {writer.error!r}"
        link.abort_writes()
        assert writer.done.wait(_PROMPT_S), "the waiting write was not given up"
        assert isinstance(writer.error, ConnectionLostError)
    finally:
        link.close()
