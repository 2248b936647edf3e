"""The conftest's guard fails a test not marked `integration` that opens a real internet
socket, pseudo-terminal or subprocess, and leaves in-process socketpairs alone."""

from __future__ import annotations

import asyncio
import os
import pty
import socket
import subprocess
import sys
from collections.abc import Callable, Iterator

import pytest

from tests.conftest import IntegrationGuard, IntegrationOnlyError


def _bind_inet() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))


def _connect_inet6() -> None:
    with socket.socket(socket.AF_INET6, socket.SOCK_STREAM) as sock:
        sock.connect(("::1", 9))


def _connect_ex_inet() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.connect_ex(("127.0.0.1", 9))


def _asyncio_connection() -> None:
    asyncio.run(asyncio.open_connection("127.0.0.1", 9))


def _asyncio_subprocess() -> None:
    async def start() -> None:
        await asyncio.create_subprocess_exec(sys.executable, "-c", "pass")

    asyncio.run(start())


# Each is looked up at call time (hence the lambdas): the guard patches os and pty per test.
OPENERS: dict[str, Callable[[], object]] = {
    "bind AF_INET": _bind_inet,
    "connect AF_INET6": _connect_inet6,
    "connect_ex AF_INET": _connect_ex_inet,
    "asyncio.open_connection": _asyncio_connection,
    "pty.openpty": lambda: pty.openpty(),  # noqa: PLW0108
    "os.openpty": lambda: os.openpty(),  # noqa: PLW0108
    "subprocess.Popen": lambda: subprocess.Popen([sys.executable, "-c", "pass"]),
    "subprocess.run": lambda: subprocess.run([sys.executable, "-c", "pass"], check=False),
    "asyncio.create_subprocess_exec": _asyncio_subprocess,
    "os.fork": lambda: os.fork(),  # noqa: PLW0108
    "os.posix_spawn": lambda: os.posix_spawn(sys.executable, [sys.executable], os.environ),
}


@pytest.fixture
def guard(integration_guard: IntegrationGuard | None) -> Iterator[IntegrationGuard]:
    """The active guard of this (unmarked) test; what it records is cleared at the end, so the
    refusals these tests provoke on purpose do not fail them."""
    assert integration_guard is not None, "the guard is off for a test not marked integration"
    yield integration_guard
    integration_guard.violations.clear()


@pytest.mark.parametrize("opener", OPENERS.values(), ids=OPENERS.keys())
def test_an_unmarked_test_that_opens_one_is_refused(
    guard: IntegrationGuard, opener: Callable[[], object]
) -> None:
    with pytest.raises(IntegrationOnlyError, match="is not marked integration"):
        opener()
    assert len(guard.violations) == 1


def test_a_refusal_the_code_swallows_still_fails_the_test(
    guard: IntegrationGuard, pytester: pytest.Pytester
) -> None:
    pytester.makeconftest("from tests.conftest import integration_guard")
    pytester.makepyfile(
        """
        import socket

        def test_hides_the_error():
            try:
                with socket.socket(socket.AF_INET) as sock:
                    sock.bind(("127.0.0.1", 0))
            except Exception:
                pass
        """
    )
    result = pytester.runpytest_inprocess(
        "-p", "no:cacheprovider", "-o", "asyncio_default_fixture_loop_scope=function"
    )
    result.assert_outcomes(passed=1, errors=1)
    result.stdout.fnmatch_lines(["*test_hides_the_error called bind*is not marked integration*"])


def test_socketpairs_and_unix_sockets_stay_allowed(guard: IntegrationGuard) -> None:
    near, far = socket.socketpair()
    with near, far:
        near.sendall(b"#ok!")
        assert far.recv(4) == b"#ok!"

    async def loop_roundtrip() -> int:  # the event loop's own socketpair
        return await asyncio.sleep(0, result=1)

    assert asyncio.run(loop_roundtrip()) == 1
    assert guard.violations == []


@pytest.mark.integration
def test_an_integration_test_is_not_guarded(integration_guard: IntegrationGuard | None) -> None:
    assert integration_guard is None
    _bind_inet()
