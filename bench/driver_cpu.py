"""Query round trip: the host's CPU time per query through the driver, against raw loops.

    python bench/driver_cpu.py [--queries 2000] [--rounds 15] [--checksum]

Builds and starts ``fast_controller.c`` (a C controller on TCP that answers at once, so that the
link and the host are timed, not the controller) and times ``#qd!`` → ``$qd.N!`` one query at a
time, four ways, each against the same controller in the same run:

* raw socket: ``sendall(b"#qd!")`` and ``recv`` until the reply's ``!`` — the least Python can do;
* ``rovlink.connect(url, keepalive=None).depth_cm()``: the blocking driver;
* raw asyncio streams: ``open_connection``, ``write``, ``readuntil(b"!")``;
* ``await rovlink.aio.connect(url, keepalive=None).depth_cm()``: the asyncio driver.

The figure that counts is the host process's CPU time per query (``time.process_time``, user +
system, every thread of this process): an idle machine's wake-up latency, which dominates the
wall-clock time and varies with the machine, does not hide what the client itself costs. The
wall-clock time per query is printed beside it. Rounds interleave the ways so that load from
elsewhere hits them alike; each client's ratio is taken against its raw peer of the same round,
and the median and spread (min–max) over the rounds are printed. Targets: blocking ≤ 1.15× raw,
asyncio ≤ 1.00× raw asyncio.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import socket
import statistics
import sys
import time
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

import rovlink
import rovlink.aio
from fast_controller import FastController, NoCompilerError, running_fast_controller
from rovlink.protocol import Command, encode

WARM_UP_QUERIES = 200
TARGETS = {"rovlink.connect": 1.15, "rovlink.aio.connect": 1.00}


@dataclass(frozen=True)
class Sample:
    """One way's queries in one round: CPU and wall-clock seconds per query."""

    cpu_s: float
    wall_s: float


def _timed(queries: int, query: Callable[[], object]) -> Sample:
    for _ in range(WARM_UP_QUERIES):
        query()
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(queries):
        query()
    return Sample((time.process_time() - cpu) / queries, (time.perf_counter() - wall) / queries)


async def _timed_async(queries: int, query: Callable[[], Awaitable[object]]) -> Sample:
    for _ in range(WARM_UP_QUERIES):
        await query()
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(queries):
        await query()
    return Sample((time.process_time() - cpu) / queries, (time.perf_counter() - wall) / queries)


def raw_socket(controller: FastController, queries: int, query: bytes) -> Sample:
    with socket.create_connection((controller.host, controller.port)) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if query != b"#qd!":
            sock.sendall(b"#crcon!")
        sendall, recv = sock.sendall, sock.recv

        def round_trip() -> None:
            sendall(query)
            reply = recv(4096)
            while not reply.endswith(b"!"):
                reply += recv(4096)

        return _timed(queries, round_trip)


def client_blocking(controller: FastController, queries: int, checksum: bool) -> Sample:
    with rovlink.connect(controller.url, keepalive=None, checksum=checksum) as rov:
        return _timed(queries, rov.depth_cm)


def raw_asyncio(controller: FastController, queries: int, query: bytes) -> Sample:
    async def main() -> Sample:
        reader, writer = await asyncio.open_connection(controller.host, controller.port)
        try:
            if query != b"#qd!":
                writer.write(b"#crcon!")

            async def round_trip() -> bytes:
                writer.write(query)
                return await reader.readuntil(b"!")

            return await _timed_async(queries, round_trip)
        finally:
            writer.close()
            await writer.wait_closed()

    return asyncio.run(main())


def client_asyncio(controller: FastController, queries: int, checksum: bool) -> Sample:
    async def main() -> Sample:
        async with rovlink.aio.connect(controller.url, keepalive=None, checksum=checksum) as rov:
            return await _timed_async(queries, rov.depth_cm)

    return asyncio.run(main())


def _pin(cpus: str) -> int | None:
    """Pin this process as ``--cpus`` asks; the CPU for the controller (None: anywhere)."""
    if cpus == "any" or not hasattr(os, "sched_setaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    host_cpu = allowed[0]
    os.sched_setaffinity(0, {host_cpu})
    return allowed[1] if cpus == "split" and len(allowed) > 1 else host_cpu


def _summary(values: list[float]) -> str:
    return f"{statistics.median(values):5.2f} ({min(values):.2f}–{max(values):.2f})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--queries", type=int, default=2000, help="queries per way per round")
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--checksum", action="store_true", help="CRC-8 checksum mode on")
    parser.add_argument(
        "--cpus", choices=("split", "same", "any"), default="split",
        help="split (default): this process on one CPU and the controller on another, so every "
        "reply wakes the host as a serial port's would; same: both on one CPU (no idle "
        "wake-ups, only the host's own work); any: where the scheduler puts them",
    )
    arguments = parser.parse_args()
    controller_cpu = _pin(arguments.cpus)
    checksum: bool = arguments.checksum
    query = encode(Command("qd"), checksum="crc8" if checksum else None)
    ways: dict[str, Callable[[FastController], Sample]] = {
        "raw socket": lambda c: raw_socket(c, arguments.queries, query),
        "rovlink.connect": lambda c: client_blocking(c, arguments.queries, checksum),
        "raw asyncio streams": lambda c: raw_asyncio(c, arguments.queries, query),
        "rovlink.aio.connect": lambda c: client_asyncio(c, arguments.queries, checksum),
    }
    peers = {"rovlink.connect": "raw socket", "rovlink.aio.connect": "raw asyncio streams"}
    try:
        with running_fast_controller(controller_cpu) as controller:
            samples: dict[str, list[Sample]] = {name: [] for name in ways}
            for _ in range(arguments.rounds):
                for name, way in ways.items():
                    samples[name].append(way(controller))
    except NoCompilerError as error:
        print(f"driver_cpu: {error}", file=sys.stderr)
        return 2

    print(f"{arguments.rounds} rounds × {arguments.queries} queries per way, "
          f"checksums {'on' if checksum else 'off'}, CPUs {arguments.cpus}, "
          f"Python {sys.version.split()[0]}")
    print(f"{'way':<22}{'CPU µs/query':>14}{'wall µs/query':>15}{'CPU × peer (min–max)':>24}"
          f"{'wall × peer':>13}")
    verdicts = []
    for name, runs in samples.items():
        cpu_us = statistics.median(s.cpu_s for s in runs) * 1e6
        wall_us = statistics.median(s.wall_s for s in runs) * 1e6
        line = f"{name:<22}{cpu_us:>14.1f}{wall_us:>15.1f}"
        peer = peers.get(name)
        if peer is not None:
            cpu_ratios = [s.cpu_s / p.cpu_s for s, p in zip(runs, samples[peer], strict=True)]
            wall_ratios = [s.wall_s / p.wall_s for s, p in zip(runs, samples[peer], strict=True)]
            line += f"{_summary(cpu_ratios):>24}{statistics.median(wall_ratios):>13.2f}"
            ratio, target = statistics.median(cpu_ratios), TARGETS[name]
            verdicts.append(f"{name}: CPU {ratio:.2f}× {peer} (target ≤ {target:.2f}×: "
                            f"{'met' if ratio <= target else 'NOT met'})")
        print(line)
    print("\n".join(verdicts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
