"""A real mosquitto on a free loopback port, with a temporary configuration and persistence."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

_START_TIMEOUT_S = 10.0


def free_tcp_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


class Mosquitto:
    """``mosquitto -c CONFIG``; :meth:`restart` keeps the port and the persisted sessions."""

    def __init__(self, workdir: Path, listener_options: str = "allow_anonymous true\n") -> None:
        executable = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        self.executable = executable
        self.port = free_tcp_port()
        self.workdir = workdir
        self.config = workdir / "mosquitto.conf"
        # As root, mosquitto would switch to the user "mosquitto", who cannot write here.
        user = "user root\n" if os.geteuid() == 0 else ""
        self.config.write_text(
            user + f"listener {self.port} 127.0.0.1\n" + listener_options + "persistence true\n"
            f"persistence_location {workdir}/\n"
            f"log_dest file {workdir}/mosquitto.log\n",
            encoding="utf-8",
        )
        self.process: subprocess.Popen[bytes] | None = None

    @property
    def url(self) -> str:
        return f"mqtt://127.0.0.1:{self.port}"

    def start(self) -> None:
        self.process = subprocess.Popen(
            [self.executable, "-c", str(self.config)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + _START_TIMEOUT_S
        while True:
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=0.5):
                    return
            except OSError:
                if self.process.poll() is not None or time.monotonic() > deadline:
                    raise AssertionError(
                        f"mosquitto did not start on port {self.port}: "
                        f"{(self.workdir / 'mosquitto.log').read_text(errors='replace')}"
                    ) from None
                time.sleep(0.05)

    def stop(self) -> None:
        if self.process is None:
            return
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self.process = None

    @contextmanager
    def stalled(self) -> Iterator[None]:
        """The broker stopped (SIGSTOP, as a machine swapping, or a debugger): its sockets stay
        open and what is sent to it waits in them; resumed (SIGCONT) on leaving."""
        assert self.process is not None
        os.kill(self.process.pid, signal.SIGSTOP)
        try:
            yield
        finally:
            os.kill(self.process.pid, signal.SIGCONT)

    def restart(self) -> None:
        self.stop()
        self.start()


def mosquitto_available() -> bool:
    return shutil.which("mosquitto") is not None or Path("/usr/sbin/mosquitto").exists()


def running_broker(workdir: Path) -> Iterator[Mosquitto]:
    """A started mosquitto for a fixture (skips the test where mosquitto is missing)."""
    if not mosquitto_available():
        pytest.skip("needs mosquitto (Debian package mosquitto)")
    mosquitto = Mosquitto(workdir)
    mosquitto.start()
    try:
        yield mosquitto
    finally:
        mosquitto.stop()
