"""Query round trip: the host's CPU time per query through the driver, against raw loops.

    python bench/driver_cpu.py [--rounds 15] [--blocks 8] [--block 250] [--checksum]
                               [--cpus split|same|any] [--poll-idle]

Builds and starts ``fast_controller.c`` (a C controller on TCP that answers at once, so that the
link and the host are timed, not the controller) and times ``#qd!`` → ``$qd.N!`` one query at a
time, four ways, against the same controller in the same run:

* raw socket: ``sendall(b"#qd!")`` and ``recv`` until the reply's ``!`` — the least Python can do;
* ``rovlink.connect(url, keepalive=None).depth_cm()``: the blocking driver;
* raw asyncio streams: ``open_connection``, ``write``, ``readuntil(b"!")``;
* ``await rovlink.aio.connect(url, keepalive=None).depth_cm()``: the asyncio driver;

and, as references without a target, the raw socket loop plus the session's own per-query
bookkeeping (``Session.fast_query`` and ``Session.receive_reply``, the drivers' shortest path):
what any client that matches replies to queries as P20 asks costs at least with this session;
and the raw socket loop plus the least a thread-safe client can keep per query at all (a lock
taken around queueing the query and around settling it, a queue, the value read by ``int``).
The same bookkeeping is then timed alone in a tight loop with no I/O, and both figures printed:
how much more the same Python code costs when it runs after each wait for a reply, with the
caches cold, than with them warm. That factor is the machine's, and it sets how far any client
written in Python can come to the raw loop.

The figure that counts is the host process's CPU time per query (``time.process_time``, user +
system, every thread of this process): an idle machine's wake-up latency, which dominates the
wall-clock time and varies with the machine, does not hide what the client itself costs. The
wall-clock time per query is printed beside it. Each client and its raw peer are connected at
once (the controller serves each connection in its own process) and take turns in blocks of
``--block`` queries, so that load from elsewhere on the machine hits both alike; a round is
``--blocks`` turns of each, its ratio the client's CPU time over the peer's, and the median and
spread (min–max) of the rounds' ratios are printed. Each turn starts with a different way, so
that no way always runs right after the same other one: the first queries after a switch of
connection cost more, and a fixed order put up to 8 % of that on one way. Targets: blocking
≤ 1.15× the raw socket, asyncio ≤ 1.00× raw asyncio streams.

``--poll-idle`` keeps the CPUs from halting while idle for the run (it holds
``/dev/cpu_dma_latency`` at 0, as ``cyclictest`` does; root only): on a virtual machine every
halt hands the CPU back to the host, and the caches with it.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import socket
import statistics
import sys
import threading
import time
from collections import deque
from collections.abc import Awaitable, Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import TypeVar

import rovlink
import rovlink.aio
from fast_controller import FastController, NoCompilerError, running_fast_controller
from rovlink.client.session import Session
from rovlink.protocol import Command, Response, encode

T = TypeVar("T")

WARM_UP_QUERIES = 200
TARGETS = {"rovlink.connect": 1.15, "rovlink.aio.connect": 1.00}
PEERS = {"rovlink.connect": "raw socket", "rovlink.aio.connect": "raw asyncio streams"}
#: The raw socket loop plus the session's per-query bookkeeping alone (see its function).
SESSION_FLOOR = "raw + session only"
#: The raw socket loop plus the least a thread-safe client keeps per query (see its function).
LEAST_CLIENT = "raw + lock, queue, int"
#: Every way, in the order the results are printed.
WAYS = (
    "raw socket",
    SESSION_FLOOR,
    LEAST_CLIENT,
    "rovlink.connect",
    "raw asyncio streams",
    "rovlink.aio.connect",
)
#: Memory written before each timed call of the bookkeeping (session_bookkeeping_swept_us):
#: about a second-level cache's size, and below and above the reach of a second-level TLB of
#: 2,048 entries of 4 KiB pages (8 MiB).
SWEEPS_MIB = (1, 8, 16)


@dataclass
class Totals:
    """One way's CPU and wall-clock seconds and queries, per round."""

    cpu_s: list[float] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    queries: list[int] = field(default_factory=list)

    def start_round(self) -> None:
        self.cpu_s.append(0.0)
        self.wall_s.append(0.0)
        self.queries.append(0)

    def add(self, cpu_s: float, wall_s: float, queries: int) -> None:
        self.cpu_s[-1] += cpu_s
        self.wall_s[-1] += wall_s
        self.queries[-1] += queries

    def per_query(self, which: list[float]) -> list[float]:
        return [seconds / count for seconds, count in zip(which, self.queries, strict=True)]


def _turns(ways: Sequence[T], count: int) -> Iterator[T]:
    """``count`` turns of every way, each turn starting with the next way (see the module's
    docstring)."""
    for turn in range(count):
        start = turn % len(ways)
        yield from ways[start:]
        yield from ways[:start]


@contextlib.contextmanager
def _idle_polling(wanted: bool) -> Iterator[None]:
    """While open, CPUs poll instead of halting when idle, if ``wanted`` (PM QoS: a latency
    of 0 µs asked through ``/dev/cpu_dma_latency``, undone when the file is closed)."""
    if not wanted:
        yield
        return
    descriptor = os.open("/dev/cpu_dma_latency", os.O_WRONLY)
    try:
        os.write(descriptor, (0).to_bytes(4, sys.byteorder))
        yield
    finally:
        os.close(descriptor)


def _block(totals: Totals, queries: int, query: Callable[[], object]) -> None:
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(queries):
        query()
    totals.add(time.process_time() - cpu, time.perf_counter() - wall, queries)


async def _async_block(
    totals: Totals, queries: int, query: Callable[[], Awaitable[object]]
) -> None:
    cpu, wall = time.process_time(), time.perf_counter()
    for _ in range(queries):
        await query()
    totals.add(time.process_time() - cpu, time.perf_counter() - wall, queries)


def raw_socket_query(
    host: str, port: int, query: bytes
) -> tuple[socket.socket, Callable[[], bytes]]:
    """A connected socket, and the least Python can do for one query on it."""
    sock = socket.create_connection((host, port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    if query != b"#qd!":
        sock.sendall(b"#crcon!")
    sendall, recv = sock.sendall, sock.recv

    def round_trip() -> bytes:
        sendall(query)
        reply = recv(4096)
        while not reply.endswith(b"!"):
            reply += recv(4096)
        return reply

    return sock, round_trip


def _session_bookkeeping(checksum: bool) -> Callable[[bytes], None]:
    """What any client keeping P20's matching must do per query, and no more: queue the query
    in a :class:`~rovlink.client.session.Session` and settle it with its reply (``fast_query``
    and ``receive_reply``, the drivers' shortest path)."""
    session = Session(checksum_enabled=checksum)
    command = Command("qd")
    fast_query, receive_reply, clock = session.fast_query, session.receive_reply, time.monotonic

    def settle(reply: bytes) -> None:
        fast_query(command, clock())
        receive_reply(reply, clock())

    return settle


def with_session_bookkeeping(raw_query: Callable[[], bytes], checksum: bool) -> Callable[[], None]:
    """The raw loop plus the session's bookkeeping of the reply it read: a floor for the
    clients."""
    settle = _session_bookkeeping(checksum)

    def round_trip() -> None:
        settle(raw_query())

    return round_trip


def with_least_client(raw_query: Callable[[], bytes], checksum: bool) -> Callable[[], int]:
    """The raw loop plus the least a client that many threads may call keeps per query: the
    query queued and taken off under a lock, and the reply's value read by ``int``. No check
    of the frame beyond its name (nor of its checksum), no counters: a floor below any real
    client's, of any design."""
    lock = threading.Lock()
    on_the_wire: deque[object] = deque()
    prefix = b"$qd."
    tail = 3 if checksum else 1  # (two hex digits of CRC-8, and the "!")

    def round_trip() -> int:
        with lock:
            on_the_wire.append(round_trip)
        reply = raw_query()
        with lock:
            on_the_wire.popleft()
        if not reply.startswith(prefix):
            raise ValueError(f"not a depth reply: {reply!r}")
        return int(reply[len(prefix) : len(reply) - tail])

    return round_trip


def session_bookkeeping_hot_us(checksum: bool, queries: int = 50_000) -> float:
    """CPU µs per query of the floor's session bookkeeping alone, in a tight loop with no I/O:
    what it costs with warm caches, to set beside what it adds after each wake-up in the run.
    The replies count up as the fast controller's do, so each is a frame not seen before."""
    settle = _session_bookkeeping(checksum)
    replies = [
        encode(Response("qd", (count % 10_000,)), checksum="crc8" if checksum else None)
        for count in range(queries)
    ]
    for reply in replies[:10_000]:  # the number tables filled, as in the run after its warm-up
        settle(reply)
    started = time.process_time()
    for reply in replies:
        settle(reply)
    return (time.process_time() - started) / queries * 1e6


def session_bookkeeping_swept_us(checksum: bool, sweep_mib: int, queries: int = 1000) -> float:
    """µs of the floor's session bookkeeping for one query run right after writing
    ``sweep_mib`` MiB of memory, as the rest of the machine does while this process sleeps: the
    median of single calls (wall clock; one thread, no I/O). It reproduces in-process, without
    the link, what the bookkeeping costs after each wait: how much of that is the caches and
    address translations the code lost while asleep."""
    settle = _session_bookkeeping(checksum)
    replies = [
        encode(Response("qd", (count % 10_000,)), checksum="crc8" if checksum else None)
        for count in range(10_000 + queries)
    ]
    for reply in replies[:10_000]:  # the number tables filled, as in the run
        settle(reply)
    sweep = bytearray(sweep_mib << 20)
    ones = b"\x01" * (len(sweep) // 64)
    clock_ns = time.perf_counter_ns
    times_ns = []
    for reply in replies[10_000:]:
        sweep[::64] = ones  # one write per cache line
        started = clock_ns()
        settle(reply)
        times_ns.append(clock_ns() - started)
    return statistics.median(times_ns) / 1000


def run_blocking(
    controller: FastController,
    arguments: argparse.Namespace,
    query: bytes,
    totals: dict[str, Totals],
) -> None:
    """The blocking client and the raw socket, in turns."""
    sock, raw_query = raw_socket_query(controller.host, controller.port, query)
    with sock, rovlink.connect(controller.url, keepalive=None, checksum=arguments.checksum) as rov:
        ways = [
            (totals["raw socket"], raw_query),
            (totals["rovlink.connect"], rov.depth_cm),
            (totals[SESSION_FLOOR], with_session_bookkeeping(raw_query, arguments.checksum)),
            (totals[LEAST_CLIENT], with_least_client(raw_query, arguments.checksum)),
        ]
        for _, way_query in ways:
            for _ in range(WARM_UP_QUERIES):
                way_query()
        for _ in range(arguments.rounds):
            for way_totals, _ in ways:
                way_totals.start_round()
            for way_totals, way_query in _turns(ways, arguments.blocks):
                _block(way_totals, arguments.block, way_query)


def run_asyncio(
    controller: FastController,
    arguments: argparse.Namespace,
    query: bytes,
    totals: dict[str, Totals],
) -> None:
    """The asyncio client and raw asyncio streams, in turns, in one event loop."""

    async def main() -> None:
        reader, writer = await asyncio.open_connection(controller.host, controller.port)
        if query != b"#qd!":
            writer.write(b"#crcon!")

        async def raw_query() -> bytes:
            writer.write(query)
            return await reader.readuntil(b"!")

        try:
            async with rovlink.aio.connect(
                controller.url, keepalive=None, checksum=arguments.checksum
            ) as rov:
                ways: list[tuple[Totals, Callable[[], Awaitable[object]]]] = [
                    (totals["raw asyncio streams"], raw_query),
                    (totals["rovlink.aio.connect"], rov.depth_cm),
                ]
                for _, way_query in ways:
                    for _ in range(WARM_UP_QUERIES):
                        await way_query()
                for _ in range(arguments.rounds):
                    for way_totals, _ in ways:
                        way_totals.start_round()
                    for way_totals, way_query in _turns(ways, arguments.blocks):
                        await _async_block(way_totals, arguments.block, way_query)
        finally:
            writer.close()
            await writer.wait_closed()

    asyncio.run(main())


def _pin(cpus: str) -> int | None:
    """Pin this process as ``--cpus`` asks; the CPU for the controller (None: anywhere)."""
    if cpus == "any" or not hasattr(os, "sched_setaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    host_cpu = allowed[0]
    os.sched_setaffinity(0, {host_cpu})
    return allowed[1] if cpus == "split" and len(allowed) > 1 else host_cpu


def _spread(values: list[float]) -> str:
    return f"{statistics.median(values):5.2f} ({min(values):.2f}–{max(values):.2f})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--blocks", type=int, default=8, help="turns of each way per round")
    parser.add_argument("--block", type=int, default=250, help="queries per turn")
    parser.add_argument("--checksum", action="store_true", help="CRC-8 checksum mode on")
    parser.add_argument(
        "--cpus",
        choices=("split", "same", "any"),
        default="split",
        help="split (default): this process on one CPU and the controller on another, so every "
        "reply wakes the host as a serial port's would; same: both on one CPU (no idle "
        "wake-ups, only the host's own work); any: where the scheduler puts them",
    )
    parser.add_argument(
        "--poll-idle",
        action="store_true",
        help="keep the CPUs from halting when idle during the run (root only)",
    )
    arguments = parser.parse_args()
    query = encode(Command("qd"), checksum="crc8" if arguments.checksum else None)
    totals = {name: Totals() for name in WAYS}
    controller_cpu = _pin(arguments.cpus)
    try:
        with (
            _idle_polling(arguments.poll_idle),
            running_fast_controller(controller_cpu) as controller,
        ):
            run_blocking(controller, arguments, query, totals)
            run_asyncio(controller, arguments, query, totals)
    except NoCompilerError as error:
        print(f"driver_cpu: {error}", file=sys.stderr)
        return 2
    except PermissionError as error:
        print(f"driver_cpu: --poll-idle needs root: {error}", file=sys.stderr)
        return 2

    print(
        f"{arguments.rounds} rounds × {arguments.blocks} turns × {arguments.block} queries per "
        f"way, checksums {'on' if arguments.checksum else 'off'}, CPUs {arguments.cpus}"
        f"{', idle CPUs polling' if arguments.poll_idle else ''}, Python {sys.version.split()[0]}"
    )
    print(
        f"{'way':<22}{'CPU µs/query':>14}{'wall µs/query':>15}{'CPU × peer (min–max)':>24}"
        f"{'wall × peer':>13}"
    )
    verdicts = []
    for name in WAYS:
        way = totals[name]
        cpu, wall = way.per_query(way.cpu_s), way.per_query(way.wall_s)
        cpu_us = statistics.median(cpu) * 1e6
        line = f"{name:<22}{cpu_us:>14.1f}{statistics.median(wall) * 1e6:>15.1f}"
        peer_name = PEERS.get(name)
        if name in (SESSION_FLOOR, LEAST_CLIENT):  # a reference, with no target of its own
            peer = totals["raw socket"]
            cpu_ratios = [a / b for a, b in zip(cpu, peer.per_query(peer.cpu_s), strict=True)]
            line += f"{_spread(cpu_ratios):>24}"
        elif peer_name is not None:
            peer = totals[peer_name]
            cpu_ratios = [a / b for a, b in zip(cpu, peer.per_query(peer.cpu_s), strict=True)]
            wall_ratios = [a / b for a, b in zip(wall, peer.per_query(peer.wall_s), strict=True)]
            ratio, target = statistics.median(cpu_ratios), TARGETS[name]
            line += f"{_spread(cpu_ratios):>24}{statistics.median(wall_ratios):>13.2f}"
            extra_us = cpu_us - statistics.median(peer.per_query(peer.cpu_s)) * 1e6
            verdict = "met" if ratio <= target else "NOT met"
            verdicts.append(
                f"{name}: CPU {ratio:.2f}× {peer_name}, {extra_us:+.1f} µs per query "
                f"(target ≤ {target:.2f}×: {verdict})"
            )
        print(line)
    floor, raw = totals[SESSION_FLOOR], totals["raw socket"]
    after_wake_us = (
        statistics.median(floor.per_query(floor.cpu_s))
        - statistics.median(raw.per_query(raw.cpu_s))
    ) * 1e6
    print(
        f"session bookkeeping per query: {session_bookkeeping_hot_us(arguments.checksum):.1f} µs "
        f"in a tight loop, {after_wake_us:.1f} µs in the run above (cold after each wait); "
        "right after writing "
        + ", ".join(
            f"{mib} MiB: {session_bookkeeping_swept_us(arguments.checksum, mib):.1f} µs"
            for mib in SWEEPS_MIB
        )
    )
    print("\n".join(verdicts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
