"""MANUAL_CONTROL to the frame on the serial line, through ``rovlink mavlink``'s bridge.

    python bench/mavlink_latency.py [--samples N]

A pymavlink ground station sends MANUAL_CONTROL over UDP to the bridge, which runs on its own
event loop in front of the simulated controller (``sim://``, real time); the time from the send
to the ``#th…!`` frame being written to the controller's port is one sample. Each sample moves
the stick, so each is a new frame. The peer, measured in the same run and interleaved with the
bridge's samples: the same message from the same ground station to a bare pymavlink receiver
(UDP, parsing, a thread wake-up) — what any MAVLink program pays before it does anything.
Target: p99 ≤ 20 ms.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import socket
import statistics
import threading
import time
from typing import Any

os.environ["MAVLINK20"] = "1"

from pymavlink import mavutil

from rovlink.aio import AsyncClient
from rovlink.bridges.mavlink.bridge import MavlinkBridge
from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint
from rovlink.bridges.mavlink.parameters import ParameterTable
from rovlink.client import ClientOptions
from rovlink.client.links import Link, PortLink
from rovlink.piloting.tracked import TrackedClient
from rovlink.sim import SimulatedPort

_WAIT_S = 2.0


class TimedLink:
    """A link that notes when each frame was written."""

    def __init__(self, inner: Link) -> None:
        self.inner = inner
        self.description = inner.description
        self.writes: list[tuple[float, bytes]] = []
        self.written = threading.Condition()

    def read_available(self, timeout_s: float) -> bytes:
        return self.inner.read_available(timeout_s)

    def write(self, data: bytes) -> None:
        self.inner.write(data)
        with self.written:
            self.writes.append((time.perf_counter(), data))
            self.written.notify_all()

    def wake(self) -> None:
        self.inner.wake()

    def close(self) -> None:
        self.inner.close()

    def wait_for(self, frame: bytes, since: int) -> float:
        deadline = time.monotonic() + _WAIT_S
        with self.written:
            while True:
                for at_s, data in self.writes[since:]:
                    if frame in data:
                        return at_s
                left_s = deadline - time.monotonic()
                if left_s <= 0:
                    raise TimeoutError(f"{frame!r} was not written")
                self.written.wait(left_s)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def start_bridge(link: TimedLink, out: str) -> tuple[asyncio.AbstractEventLoop, Any]:
    ready = threading.Event()
    holder: dict[str, Any] = {}

    async def serve() -> None:
        options = ClientOptions(keepalive_s=1.0, timeout_s=2.0, boot_timeout_s=None)
        client = await AsyncClient(link, options).open()
        bridge = MavlinkBridge(TrackedClient(client), MavlinkEndpoint(out), ParameterTable())
        holder["loop"] = asyncio.get_running_loop()
        holder["task"] = asyncio.ensure_future(bridge.run())
        ready.set()
        with contextlib.suppress(asyncio.CancelledError):
            await holder["task"]
        await client.close()

    thread = threading.Thread(target=lambda: asyncio.run(serve()), daemon=True)
    thread.start()
    ready.wait(10)
    return holder["loop"], holder["task"]


def percentiles(samples_s: list[float]) -> str:
    ordered = sorted(samples_s)
    cuts = statistics.quantiles(ordered, n=100, method="inclusive")
    return (
        f"p50 {cuts[49] * 1000:6.2f} ms  p90 {cuts[89] * 1000:6.2f} ms  "
        f"p99 {cuts[98] * 1000:6.2f} ms  max {ordered[-1] * 1000:6.2f} ms"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=500)
    args = parser.parse_args()

    port = SimulatedPort(seed=1)
    port.start(realtime=True)
    link = TimedLink(PortLink(port, "simulated controller"))
    gcs_port = free_udp_port()
    loop, task = start_bridge(link, f"udpout:127.0.0.1:{gcs_port}")
    gcs: Any = mavutil.mavlink_connection(
        f"udpin:127.0.0.1:{gcs_port}", source_system=255, dialect="ardupilotmega"
    )
    gcs.wait_heartbeat(timeout=10)

    # The peer: a bare pymavlink receiver of the same messages.
    peer_port = free_udp_port()
    peer: Any = mavutil.mavlink_connection(f"udpin:127.0.0.1:{peer_port}", dialect="ardupilotmega")
    to_peer: Any = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{peer_port}", source_system=255, dialect="ardupilotmega"
    )
    peer_received: list[float] = []
    peer_got = threading.Event()

    def receive_at_peer() -> None:
        while True:
            message = peer.recv_match(type="MANUAL_CONTROL", blocking=True, timeout=1.0)
            if message is not None:
                peer_received.append(time.perf_counter())
                peer_got.set()

    threading.Thread(target=receive_at_peer, daemon=True).start()

    gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
    gcs.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
    gcs.recv_match(type="COMMAND_ACK", blocking=True, timeout=5)

    bridge_s: list[float] = []
    peer_s: list[float] = []
    last_beat_s = time.monotonic()
    for sample in range(args.samples):
        if time.monotonic() - last_beat_s > 0.5:
            gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
            last_beat_s = time.monotonic()
        power = 40 + sample % 2 * 10  # 40 % / 50 %: every sample a new frame
        frame = f"#th.0.{power}!".encode()
        mark = len(link.writes)
        sent_s = time.perf_counter()
        gcs.mav.manual_control_send(1, power * 10, 0, 500, 0, 0)
        bridge_s.append(link.wait_for(frame, mark) - sent_s)

        peer_got.clear()
        count = len(peer_received)
        sent_s = time.perf_counter()
        to_peer.mav.manual_control_send(1, power * 10, 0, 500, 0, 0)
        peer_got.wait(_WAIT_S)
        peer_s.append(peer_received[count] - sent_s)
        time.sleep(0.02)  # a joystick at ~40 Hz

    loop.call_soon_threadsafe(task.cancel)
    print(f"MANUAL_CONTROL → wire frame, {args.samples} samples (target p99 ≤ 20 ms)")
    print(f"  rovlink mavlink bridge    {percentiles(bridge_s)}")
    print(f"  bare pymavlink receiver   {percentiles(peer_s)}")
    ratio = statistics.median(bridge_s) / statistics.median(peer_s)
    print(f"  median ratio bridge / bare receiver: {ratio:.1f}×")


if __name__ == "__main__":
    main()
