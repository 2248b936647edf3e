"""A program that ends without closing its blocking client (the end of its script, an uncaught
error) has it send the ``#stop!`` of ``close()`` on the way out: the robot it moved is stopped at
once. Before, the process ended with the robot driving on until the controller's link-loss
watchdog (2 s)."""

from __future__ import annotations

import asyncio
import logging
import socket
import subprocess
import sys
import threading

import pytest

import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.client import links
from rovlink.client.links import SocketLink
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    ThreadCall,
    client_options,
    fill_line,
    wait_until,
)
from tests.client.fake_controller import FakeController, FakeControllerServer
from tests.rovlink_process import rovlink_environment

pytestmark = pytest.mark.integration

_PROGRAM = """
import sys
import threading
import rovlink
rov = rovlink.connect(sys.argv[1], keepalive=None, boot_timeout=None)
rov.start()
rov.move(90, 40)
assert rov.depth_cm() == 123
if sys.argv[2] == "raises":
    raise RuntimeError("the program fails")
"""


def _run_program(source: str, *argv: str) -> subprocess.CompletedProcess[str]:
    """Run ``source`` as a Python program with ``argv``, to its end."""
    return subprocess.run(
        [sys.executable, "-c", source, *argv],
        env=rovlink_environment(),
        capture_output=True,
        check=False,
        text=True,
        timeout=CONDITION_TIMEOUT_S * 2,
    )


@pytest.mark.parametrize("ending", ["ends", "raises"])
def test_a_program_that_ends_without_closing_its_client_stops_the_robot(
    port: FakeControllerServer, ending: str
) -> None:
    child = _run_program(_PROGRAM, port.url, ending)
    assert child.returncode == (1 if ending == "raises" else 0), child.stderr
    (fake,) = port.fakes
    assert fake.wait_for(lambda f: f.frames()[-1:] == ["#stop!"]), fake.frames()
    assert fake.frames() == ["#crcoff!", "#start!", "#th.90.40!", "#qd!", "#stop!"]


_ASYNC_PROGRAM = """
import asyncio, sys
import rovlink.aio

async def main() -> None:
    rov = await rovlink.aio.connect(sys.argv[1], keepalive=None, boot_timeout=None)
    await rov.start()
    await rov.move(90, 40)
    assert await rov.depth_cm() == 123

asyncio.run(main())
"""


def test_an_asyncio_program_that_ends_without_closing_its_client_stops_the_robot(
    port: FakeControllerServer,
) -> None:
    child = _run_program(_ASYNC_PROGRAM, port.url)
    assert child.returncode == 0, child.stderr
    (fake,) = port.fakes
    assert fake.wait_for(lambda f: f.frames()[-1:] == ["#stop!"]), fake.frames()
    assert fake.frames() == ["#crcoff!", "#start!", "#th.90.40!", "#qd!", "#stop!"]


_FORKING_PROGRAM = """
import os, sys
import rovlink
rov = rovlink.connect(sys.argv[1], keepalive=None, boot_timeout=None)
rov.start()
rov.move(90, 40)
child = os.fork()
if child == 0:
    sys.exit(0)  # (the end of a child's work: its exit handlers run)
os.waitpid(child, 0)
assert rov.depth_cm() == 123
os._exit(0)  # (the parent's own stop at exit is not what this looks at)
"""


def test_a_forked_child_that_ends_does_not_stop_the_robot_of_its_parent(
    port: FakeControllerServer,
) -> None:
    # A child made with os.fork() shares its parent's port, not its driving: its exit sent the
    # #stop! of the parent's open client, and stopped the robot under the parent.
    child = _run_program(_FORKING_PROGRAM, port.url)
    assert child.returncode == 0, child.stderr
    (fake,) = port.fakes
    assert fake.wait_for(lambda f: "#qd!" in f.frames()), fake.frames()
    assert fake.frames() == ["#crcoff!", "#start!", "#th.90.40!", "#qd!"]


_FORKED_CHILD_USING_THE_CLIENT = """
import os, sys
import rovlink
from rovlink.client import ClientError
with rovlink.connect(sys.argv[1], keepalive=None, boot_timeout=None) as rov:
    rov.start()
    rov.move(90, 40)
    child = os.fork()
    if child == 0:
        for call in (rov.depth_cm, lambda: rov.move(0, 10), rov.stop):
            try:
                call()
            except ClientError as error:
                print(error)
        rov.close()
        sys.exit(0)  # (and leaves the with block: an exception)
    os.waitpid(child, 0)
    assert rov.depth_cm() == 123
    os._exit(0)
"""


def test_a_forked_child_cannot_use_or_close_the_client_of_its_parent(
    port: FakeControllerServer,
) -> None:
    # The child wrote its queries and commands on the parent's port (and read its replies),
    # and its close(), or leaving the with block, sent #stop! and shut the parent's link down.
    child = _run_program(_FORKED_CHILD_USING_THE_CLIENT, port.url)
    assert child.returncode == 0, child.stderr
    (fake,) = port.fakes
    assert fake.wait_for(lambda f: "#qd!" in f.frames()), fake.frames()
    assert fake.frames() == ["#crcoff!", "#start!", "#th.90.40!", "#qd!"]
    said = child.stdout.splitlines()
    assert len(said) == 3, child.stdout
    assert all("os.fork()" in line and "connect a client of its own" in line for line in said)


_FORKED_CHILD_USING_THE_ASYNC_CLIENT = """
import asyncio, os, sys
import rovlink.aio
from rovlink.client import ClientError

async def drive() -> rovlink.aio.AsyncClient:
    rov = await rovlink.aio.connect(sys.argv[1], keepalive=None, boot_timeout=None)
    await rov.start()
    await rov.move(90, 40)
    assert await rov.depth_cm() == 123
    return rov

rov = asyncio.run(drive())
child = os.fork()
if child == 0:
    print(rov.emergency_stop())
    try:
        asyncio.run(rov.stop())
    except ClientError as error:
        print(error)
    asyncio.run(rov.close())
    sys.exit(0)
os.waitpid(child, 0)
assert rov.emergency_stop()  # (the parent's link is still up)
os._exit(0)
"""


def test_a_forked_child_cannot_use_or_close_the_asyncio_client_of_its_parent(
    port: FakeControllerServer,
) -> None:
    child = _run_program(_FORKED_CHILD_USING_THE_ASYNC_CLIENT, port.url)
    assert child.returncode == 0, child.stderr
    (fake,) = port.fakes
    assert fake.wait_for(lambda f: "#stop!" in f.frames()), fake.frames()
    assert fake.frames() == ["#crcoff!", "#start!", "#th.90.40!", "#qd!", "#stop!"]
    said = child.stdout.splitlines()
    assert said[0] == "False", child.stdout
    assert "os.fork()" in said[1], child.stdout


@pytest.mark.usefixtures("long_write_timeout")
def test_at_exit_an_asyncio_client_on_a_line_that_takes_nothing_does_not_hold_the_exit(
    caplog: pytest.LogCaptureFixture,
) -> None:
    ours, theirs = socket.socketpair()  # nobody reads the far end
    link = SocketLink(ours, "socket pair")

    async def drive() -> AsyncClient:
        rov = await AsyncClient(link, client_options()).open()
        await rov.move(0, 40)
        return rov

    rov = asyncio.run(drive())  # the program's loop ends without close()
    try:
        fill_line(link)  # the line takes nothing more
        with caplog.at_level(logging.WARNING, logger="rovlink.client"):
            exiting = ThreadCall(rov._stop_at_exit)  # what the atexit handler does for it
            assert exiting.done.wait(CONDITION_TIMEOUT_S), "the exit waits for the write"
        assert exiting.error is None
        assert "#stop! not written within 0.5 s" in caplog.text
    finally:
        theirs.close()  # (the write still waiting fails now)
        asyncio.run(rov.close())


def _stop_writers(port: str) -> list[threading.Thread]:
    """The threads writing the #stop! of a client on ``port`` (named after its description)."""
    return [
        thread
        for thread in threading.enumerate()
        if thread.name.startswith("rovlink stop") and port in thread.name
    ]


@pytest.mark.usefixtures("long_write_timeout")
def test_closing_in_a_later_loop_on_a_line_that_takes_nothing_leaves_no_write_under_way(
    pty_fake: tuple[FakeController, str],
) -> None:
    # The #stop! not written within its 0.5 s is given up before the port is closed: a write
    # still waiting then would go to whatever the system next opens under that descriptor.
    # (A pseudo-terminal: closing it does not wake a write waiting for room, as a socket's
    # shutdown does.)
    fake, path = pty_fake

    async def drive() -> AsyncClient:
        rov = await rovlink.aio.connect(path, keepalive=None, boot_timeout=None)
        await rov.move(0, 40)
        return rov

    rov = asyncio.run(drive())
    fake.stop_reading()
    link = rov._link
    assert isinstance(link, links.FdLink)
    fill_line(link)  # the line takes nothing more
    closing = ThreadCall(lambda: asyncio.run(rov.close()))  # in a later event loop
    assert closing.done.wait(CONDITION_TIMEOUT_S), "close() waits for the write"
    assert closing.error is None
    assert wait_until(lambda: not _stop_writers(path)), "a #stop! still waits on the closed port"
