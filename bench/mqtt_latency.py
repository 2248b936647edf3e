"""Telemetry through ``rovlink mqtt``: controller → bridge → broker → subscriber, at 20 Hz.

    python bench/mqtt_latency.py [--seconds S] [--rate HZ] [--broker mqtt://HOST:PORT]

Starts a mosquitto on a free loopback port (or uses ``--broker``), bridges a simulated robot
(``sim://``, real time) at ``--rate`` readings a second, and subscribes to its telemetry. One
sample is the time from the host receiving a ``#qsa!`` reply (the client's event hook) to a
subscriber receiving that reading from the broker (matched by ``seq``). The peer, in the same
run and at the same rate: a bare aiomqtt client publishing a payload of the same size to the
same broker and subscriber — the broker hop every MQTT program pays.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import shutil
import socket
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import aiomqtt

from rovlink.aio import AsyncClient
from rovlink.bridges.mqtt.bridge import MqttBridge
from rovlink.bridges.mqtt.broker import BrokerSettings, parse_broker_url
from rovlink.client import ClientOptions
from rovlink.client.events import ClientEvent, ReplyReceived
from rovlink.client.links import PortLink
from rovlink.piloting.tracked import TrackedClient
from rovlink.sim import SimulatedPort


def free_tcp_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def start_mosquitto(workdir: Path) -> tuple[subprocess.Popen[bytes], int]:
    port = free_tcp_port()
    config = workdir / "mosquitto.conf"
    config.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\n", encoding="utf-8")
    executable = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
    process = subprocess.Popen([executable, "-c", str(config)], stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 10
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            return process, port
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


def percentiles(samples_s: list[float]) -> str:
    ordered = sorted(samples_s)
    cuts = statistics.quantiles(ordered, n=100, method="inclusive")
    return (
        f"p50 {cuts[49] * 1000:6.2f} ms  p90 {cuts[89] * 1000:6.2f} ms  "
        f"p99 {cuts[98] * 1000:6.2f} ms  max {ordered[-1] * 1000:6.2f} ms"
    )


async def measure(host: str, port: int, seconds: float, rate_hz: float) -> None:
    sim = SimulatedPort(seed=1)
    sim.start(realtime=True)
    options = ClientOptions(keepalive_s=1.0, timeout_s=2.0, boot_timeout_s=None)
    client = await AsyncClient(PortLink(sim, "simulated controller"), options).open()
    replied_s: list[float] = []

    def on_event(event: ClientEvent) -> None:
        if isinstance(event, ReplyReceived) and event.query.name == "qsa":
            replied_s.append(time.perf_counter())

    client.subscribe(on_event)
    bridge = MqttBridge(TrackedClient(client), BrokerSettings(host, port), "bench", rate_hz=rate_hz)
    bridge_samples: list[float] = []
    peer_samples: list[float] = []
    peer_sent: dict[int, float] = {}
    received_seq: list[int] = []

    async with aiomqtt.Client(host, port) as sub, aiomqtt.Client(host, port) as peer:
        await sub.subscribe("rovlink/bench/telemetry", qos=0)
        await sub.subscribe("bench/peer", qos=0)

        async def collect() -> None:
            async for message in sub.messages:
                now_s = time.perf_counter()
                assert isinstance(message.payload, bytes)
                data = json.loads(message.payload)
                if message.topic.value == "bench/peer":
                    peer_samples.append(now_s - peer_sent[data["seq"]])
                else:
                    received_seq.append(data["seq"])
                    if data["seq"] <= len(replied_s):
                        bridge_samples.append(now_s - replied_s[data["seq"] - 1])

        async def publish_peer() -> None:
            template = {"robot": "bench", "at": 0.0, "seq": 0, "depth_cm": 0, "pressure_raw": 20,
                        "leak": False, "roll_deg": 0, "pitch_deg": 0, "heading_deg": 0}  # fmt: skip
            sequence = 0
            while True:
                sequence += 1
                template["seq"] = sequence
                peer_sent[sequence] = time.perf_counter()
                await peer.publish("bench/peer", json.dumps(template), qos=0)
                await asyncio.sleep(1 / rate_hz)

        tasks = [
            asyncio.ensure_future(collect()),
            asyncio.ensure_future(bridge.run()),
            asyncio.ensure_future(publish_peer()),
        ]
        await asyncio.sleep(1.0)  # connected and polling
        bridge_samples.clear()
        peer_samples.clear()
        first_seq = bridge.sequence
        await asyncio.sleep(seconds)
        last_seq = bridge.sequence
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    await client.close()
    sim.close()

    got = {seq for seq in received_seq if first_seq < seq <= last_seq}
    readings = last_seq - first_seq
    print(f"telemetry at {rate_hz:g} Hz for {seconds:g} s, controller → broker → subscriber")
    print(f"  readings published {readings} ({readings / seconds:.1f}/s), received {len(got)}")
    print(f"  rovlink mqtt bridge     {percentiles(bridge_samples)}")
    print(f"  bare aiomqtt publisher  {percentiles(peer_samples)}")
    ratio = statistics.median(bridge_samples) / statistics.median(peer_samples)
    print(f"  median ratio bridge / bare publisher: {ratio:.1f}×")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    parser.add_argument("--rate", type=float, default=20.0)
    parser.add_argument("--broker", default=None, help="an existing broker (default: start one)")
    args = parser.parse_args()
    if args.broker is not None:
        host, port, _ = parse_broker_url(args.broker)
        asyncio.run(measure(host, port, args.seconds, args.rate))
        return
    with tempfile.TemporaryDirectory() as workdir:
        broker, port = start_mosquitto(Path(workdir))
        try:
            asyncio.run(measure("127.0.0.1", port, args.seconds, args.rate))
        finally:
            broker.terminate()
            broker.wait()


if __name__ == "__main__":
    main()
