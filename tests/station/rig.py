"""Test rig for the web station: a simulated robot on TCP that records every frame it receives,
and ``rovlink web`` in a subprocess, as a user runs it."""

from __future__ import annotations

import re
import shutil
import subprocess
import threading
import time
from collections.abc import Callable, Hashable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from rovlink.protocol import Command, Decoder, Frame
from rovlink.sim.server import SimServer
from tests.rovlink_process import running_rovlink

_URL = re.compile(r"http://\S+?/(?:\?token=[\w-]+)?(?=[ ;]|$)")
_READY_TIMEOUT_S = 30.0
#: Debian's chromium, which the browser tests drive.
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--headless",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


@dataclass(frozen=True)
class Received:
    """A frame the controller received, and when (``time.monotonic``)."""

    at_s: float
    command: Command

    @property
    def text(self) -> str:
        return str(self.command)


class ControllerLine:
    """A simulated robot served on TCP (and, with ``pty``, a PTY) in a thread; every frame that
    reaches its controller is recorded with the time it arrived. ``wait_for`` waits on a
    condition, with a timeout."""

    def __init__(self, *, seed: int = 1, pty: bool = False) -> None:
        self.server = SimServer(seed=seed)
        host, port = self.server.listen_tcp()
        self.url = f"socket://{host}:{port}"
        #: With ``pty``: a second line, for a bystander's tool (its frames are recorded too).
        self.pty_path = self.server.open_pty() if pty else None
        self.received: list[Received] = []
        self._changed = threading.Condition()
        self._decoder = Decoder()
        robot = self.server.robot
        deliver = robot.receive

        def receive(data: bytes, line: Hashable = None) -> None:
            now = time.monotonic()
            frames = [
                Received(now, event.message)
                for event in self._decoder.feed(data)
                if isinstance(event, Frame) and isinstance(event.message, Command)
            ]
            deliver(data, line)
            if frames:
                with self._changed:
                    self.received.extend(frames)
                    self._changed.notify_all()

        robot.receive = receive  # type: ignore[method-assign]
        self._stopping = threading.Event()
        self._thread = threading.Thread(
            target=self.server.serve, args=(self._stopping.is_set,), daemon=True
        )
        self._thread.start()

    def stop_replying(self) -> None:
        """From now on the controller hears and obeys every frame but nothing it writes reaches
        the station (its TX wire broke, or its reply path hangs while its motor loop runs)."""
        controller = self.server.robot.controller
        controller._write = lambda data: None
        controller._write_to_every_line = lambda data: None

    @property
    def controller_locked(self) -> bool:
        return self.server.robot.controller.locked

    def mark(self) -> int:
        """The number of frames received so far (``wait_for(..., after=mark)``)."""
        with self._changed:
            return len(self.received)

    def frames(self, after: int = 0, *, commands_only: bool = False) -> list[str]:
        """The frames received after index ``after``; queries left out with ``commands_only``."""
        with self._changed:
            received = self.received[after:]
        return [
            item.text for item in received if not (commands_only and item.command.spec.is_query)
        ]

    def wait_for(
        self, wanted: Callable[[str], bool] | str, *, after: int = 0, timeout_s: float = 10.0
    ) -> Received:
        """The first frame after index ``after`` that matches; AssertionError after the timeout."""
        matches = wanted if callable(wanted) else (lambda text: text == wanted)
        deadline = time.monotonic() + timeout_s
        index = after
        with self._changed:
            while True:
                while index < len(self.received):
                    item = self.received[index]
                    index += 1
                    if matches(item.text):
                        return item
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    seen = [
                        item.text
                        for item in self.received[after:]
                        if not item.command.spec.is_query
                    ]
                    raise AssertionError(f"no frame {wanted!r} within {timeout_s} s; got {seen}")
                self._changed.wait(remaining)

    def wait_until(self, condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
        """Wait until ``condition()`` (checked as frames arrive and every 20 ms)."""
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while not condition():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError("condition not met in time")
                self._changed.wait(min(remaining, 0.02))

    def close(self) -> None:
        self._stopping.set()
        self._thread.join(timeout=5)
        self.server.close()


@dataclass
class StationProcess:
    """A running ``rovlink web`` and the page URL it printed."""

    process: subprocess.Popen[str]
    url: str

    @property
    def base(self) -> str:
        """The URL without the token."""
        return self.url.split("?", 1)[0]

    @property
    def ws_url(self) -> str:
        return "ws" + self.base[len("http") :] + "ws"


@contextmanager
def running_station(robot_url: str, *arguments: str) -> Iterator[StationProcess]:
    """Start ``rovlink web ROBOT_URL --port 0 ARGUMENTS``, wait for its ready line, stop it."""
    with running_rovlink(
        "web",
        robot_url,
        "--port",
        "0",
        *arguments,
        ready_timeout_s=_READY_TIMEOUT_S,
        stderr=subprocess.PIPE,
    ) as (process, line):
        urls = _URL.findall(line)
        if "ready" not in line or not urls:
            _, errors = process.communicate(timeout=5)
            raise AssertionError(f"unexpected output from rovlink web: {line!r} {errors!r}")
        yield StationProcess(process, urls[-1])
