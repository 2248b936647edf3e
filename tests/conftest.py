"""Settings for the whole suite."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
from collections.abc import Callable, Iterator
from typing import Any, NoReturn

import pytest
from hypothesis import settings

# The guard's own test runs a small suite in-process with pytester.
pytest_plugins = ["pytester"]

# Many tests end a command with Ctrl-C (SIGINT) or SIGQUIT as a user does. A shell starts a
# background job (`pytest &`, or two suites at once) with both ignored, every process it starts
# inherits that, and rovlink keeps a signal ignored on entry (as `nohup` asks): those tests would
# then wait for an exit that never comes. A handler here makes each command start with the default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
if signal.getsignal(signal.SIGQUIT) is signal.SIG_IGN:
    signal.signal(signal.SIGQUIT, signal.SIG_DFL)

# Property tests check results, not speed: on a loaded machine one example can take longer than
# Hypothesis's default deadline of 200 ms, which would fail the run through no fault of the code.
settings.register_profile("rovlink", deadline=None)
settings.load_profile("rovlink")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """In CI (ROVLINK_FAIL_ON_SKIP=1) a skipped test fails the run: a missing tool is a broken
    machine, not a pass."""
    if os.environ.get("ROVLINK_FAIL_ON_SKIP") != "1" or exitstatus != 0:
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = reporter.stats.get("skipped", []) if reporter is not None else []
    if skipped:
        reasons = sorted(
            {
                str(report.longrepr[-1])
                if isinstance(report.longrepr, tuple)
                else str(report.longrepr)
                for report in skipped
            }
        )
        print(f"\n{len(skipped)} test(s) skipped in CI: " + "; ".join(reasons))
        session.exitstatus = 1


class IntegrationOnlyError(RuntimeError):
    """A test not marked `integration` opened a real socket, pseudo-terminal or process."""


class IntegrationGuard:
    """Makes a test that is not marked `integration` fail when it opens an internet socket
    (bind/connect on AF_INET/AF_INET6), a pseudo-terminal or a subprocess.

    The call raises `IntegrationOnlyError` at once, and the test fails at teardown even if the code
    under test caught it. AF_UNIX sockets stay allowed: a socketpair is an in-process pipe
    (asyncio's loop and the suite's fake controllers use one) and needs no port.
    """

    def __init__(self, test_id: str) -> None:
        self.test_id = test_id
        self.violations: list[str] = []

    def refuse(self, what: str) -> NoReturn:
        """Record that the test used `what`, and raise."""
        message = (
            f"{self.test_id} {what} but is not marked integration: "
            'mark it `@pytest.mark.integration` (or `pytestmark`) so `-m "not integration"` '
            "stays free of real PTYs, sockets and subprocesses"
        )
        self.violations.append(message)
        raise IntegrationOnlyError(message)

    def install(self, monkeypatch: pytest.MonkeyPatch) -> None:
        """Wrap every way to open one of them, for this test only."""
        for name in ("bind", "connect", "connect_ex"):
            monkeypatch.setattr(socket.socket, name, self._guarded_socket_call(name))
        for name in ("openpty", "posix_openpt", "fork", "forkpty", "posix_spawn", "posix_spawnp"):
            if hasattr(os, name):
                monkeypatch.setattr(os, name, self._refusing(f"called os.{name}"))
        original_popen_init = subprocess.Popen.__init__

        def guarded_popen_init(popen: Any, *args: Any, **kwargs: Any) -> None:
            command = args[0] if args else kwargs.get("args")
            program = command[0] if isinstance(command, list | tuple) else command
            self.refuse(f"started a subprocess ({program!r})")
            original_popen_init(popen, *args, **kwargs)  # pragma: no cover

        # asyncio.create_subprocess_* starts its process through subprocess.Popen too.
        monkeypatch.setattr(subprocess.Popen, "__init__", guarded_popen_init)

    def _guarded_socket_call(self, name: str) -> Callable[..., Any]:
        original = getattr(socket.socket, name)

        def guarded(sock: socket.socket, address: Any, *args: Any) -> Any:
            if sock.family in (socket.AF_INET, socket.AF_INET6):
                self.refuse(f"called {name}{address!r} on an internet socket")
            return original(sock, address, *args)

        return guarded

    def _refusing(self, what: str) -> Callable[..., NoReturn]:
        def refusing(*_args: Any, **_kwargs: Any) -> NoReturn:
            self.refuse(what)

        return refusing


@pytest.fixture(autouse=True)
def integration_guard(
    request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> Iterator[IntegrationGuard | None]:
    """Hold a test not marked `integration` to what `-m "not integration"` promises."""
    if request.node.get_closest_marker("integration") is not None:
        yield None
        return
    guard = IntegrationGuard(request.node.nodeid)
    guard.install(monkeypatch)
    yield guard
    if guard.violations:
        pytest.fail(guard.violations[0], pytrace=False)
