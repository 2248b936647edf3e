"""Test rig for the operator tools: a simulated controller (or a silent one) behind a link that
records every byte the host writes, and asyncio clients over it."""

from __future__ import annotations

import asyncio
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

from rovlink.aio import AsyncClient
from rovlink.client import ClientOptions
from rovlink.client.links import Link, PortLink, SocketLink
from rovlink.client.options import StrayCallback
from rovlink.controller import ControllerConfig
from rovlink.sim import SimConfig, SimulatedPort
from tests.client.conftest import REPLY_TIMEOUT_S


class RecordingLink:
    """Wraps a link and records what the host writes to it: the frames actually sent."""

    def __init__(self, inner: Link) -> None:
        self.inner = inner
        self.description = inner.description
        # (The simulator's writes never wait: the asyncio client writes them at once.)
        self.writes_may_wait: bool = getattr(inner, "writes_may_wait", True)
        self.written = bytearray()
        self._lock = threading.Lock()

    def read_available(self, timeout_s: float) -> bytes:
        return self.inner.read_available(timeout_s)

    def write(self, data: bytes) -> None:
        with self._lock:
            self.written += data
        self.inner.write(data)

    def wake(self) -> None:
        self.inner.wake()

    def close(self) -> None:
        self.inner.close()

    def frames(self) -> list[str]:
        """The frames written so far, as text."""
        with self._lock:
            text = self.written.decode("ascii")
        return [frame + "!" for frame in text.split("!") if frame]


class SilenceableLink(RecordingLink):
    """A recording link whose controller can be made silent (``silent.set()``): what it writes
    is lost, as a stopped, hung or rebooting controller's would be; what the host writes still
    reaches it."""

    def __init__(self, inner: Link) -> None:
        super().__init__(inner)
        self.silent = threading.Event()

    def read_available(self, timeout_s: float) -> bytes:
        data = self.inner.read_available(timeout_s)
        return b"" if self.silent.is_set() else data


@dataclass
class Rig:
    """A simulated controller stepped by hand (``port.advance``) and the recording link to it."""

    port: SimulatedPort
    link: RecordingLink
    clients: list[AsyncClient] = field(default_factory=list)

    @classmethod
    def simulated(cls, *, leak_at_s: float | None = None) -> Rig:
        """The default simulated robot, without the link-loss failsafe: a test jumps simulated
        time ahead between the host's frames, which the watchdog would take for a dead link."""
        config = SimConfig(controller=ControllerConfig(watchdog_s=0.0))
        port = SimulatedPort(config, seed=1)
        if leak_at_s is not None:
            port.robot.inject_leak(at_s=leak_at_s)
        return cls(port, RecordingLink(PortLink(port, "simulated controller")))

    async def connect(
        self, on_stray: StrayCallback | None = None, **options: object
    ) -> AsyncClient:
        """An asyncio client on the link (no keep-alives: tests count frames)."""
        settings: dict[str, object] = {
            "keepalive_s": None,
            "timeout_s": REPLY_TIMEOUT_S,
            "boot_timeout_s": None,
            "motion_timeout_s": None,
            "on_stray": on_stray,
        }
        settings.update(options)
        client = AsyncClient(self.link, ClientOptions(**settings))  # type: ignore[arg-type]
        self.clients.append(client)
        return await client.open()

    def frames(self) -> list[str]:
        return self.link.frames()


class SilentController:
    """The far end of a socket pair that reads everything and never answers."""

    def __init__(self) -> None:
        self.host_end, self._far_end = socket.socketpair()
        self.received = bytearray()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        while True:
            try:
                data = self._far_end.recv(4096)
            except OSError:
                return
            if not data:
                return
            self.received += data

    def link(self) -> RecordingLink:
        return RecordingLink(SocketLink(self.host_end, "silent controller"))

    def close(self) -> None:
        self._far_end.close()
        self._thread.join(timeout=2.0)


async def until(predicate: Callable[[], bool], timeout_s: float = 5.0) -> None:
    """Wait until ``predicate()`` holds, checking between event-loop turns; fail after a timeout."""
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout_s
    while not predicate():
        if loop.time() > deadline:
            raise AssertionError(f"condition not met within {timeout_s} s")
        await asyncio.sleep(0.01)
