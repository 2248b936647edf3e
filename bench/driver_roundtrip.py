"""Query round trip through the driver against a raw round trip to the same controller.

    python bench/driver_roundtrip.py [--queries 500] [--rounds 20] [--baud N]

Starts ``rovlink sim --pty --tcp 0`` (paced at ``--baud`` if given) and times ``#qd!`` → ``$qd.N!``
one query at a time, over the pseudo-terminal and over TCP, five ways:

* raw: the least Python can do — write the frame, ``select`` and read whatever is waiting
  until the reply's ``!`` (the peer every ratio is against);
* pyserial ``read_until``: ``port.write`` and ``port.read_until(b"!")``, as a simple script would;
* ``rovlink.connect(url).depth_cm()``: the blocking driver (reader thread, reply matching);
* ``await rovlink.aio.connect(url).depth_cm()``: the asyncio driver, one query at a time.

Rounds interleave the ways so that load from elsewhere on the machine hits them alike: each
round runs every way once, back to back. The latencies are medians over all queries; the ratio
is the median over the rounds of each round's median against the raw median of the same round.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import select
import socket
import statistics
import time
from collections.abc import Callable

import serial

import rovlink
import rovlink.aio
from driver_sim import Sim, running_sim

QUERY = b"#qd!"
WARM_UP_QUERIES = 50
#: The simulator takes one TCP client at a time and may not have seen the last one leave yet.
CONNECT_ATTEMPTS = 5
RETRY_AFTER_S = 0.1

Timings = list[float]


def _read_reply(fd: int) -> None:
    reply = b""
    while not reply.endswith(b"!"):
        select.select([fd], [], [], 2.0)
        reply += os.read(fd, 4096)


def raw_pty(sim: Sim, queries: int, baud: int) -> Timings:
    # pyserial opens and configures the terminal (raw mode, speed); then only the descriptor.
    with serial.Serial(sim.pty_path, baudrate=baud, timeout=1) as port:
        fd = port.fileno()
        return _time_queries(queries, lambda: (os.write(fd, QUERY), _read_reply(fd)))


def raw_tcp(sim: Sim, queries: int, baud: int) -> Timings:
    with socket.create_connection((sim.tcp_host, sim.tcp_port)) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        fd = sock.fileno()
        return _time_queries(queries, lambda: (sock.sendall(QUERY), _read_reply(fd)))


def pyserial_read_until(url: str) -> Callable[[Sim, int, int], Timings]:
    def run(sim: Sim, queries: int, baud: int) -> Timings:
        with serial.serial_for_url(url.format(sim=sim), baudrate=baud, timeout=2) as port:
            return _time_queries(queries, lambda: (port.write(QUERY), port.read_until(b"!")))
    return run


def driver_blocking(url: str) -> Callable[[Sim, int, int], Timings]:
    def run(sim: Sim, queries: int, baud: int) -> Timings:
        with rovlink.connect(url.format(sim=sim), baudrate=baud) as rov:
            return _time_queries(queries, rov.depth_cm)
    return run


def driver_asyncio(url: str) -> Callable[[Sim, int, int], Timings]:
    def run(sim: Sim, queries: int, baud: int) -> Timings:
        async def main() -> Timings:
            async with rovlink.aio.connect(url.format(sim=sim), baudrate=baud) as rov:
                for _ in range(WARM_UP_QUERIES):
                    await rov.depth_cm()
                timings = []
                for _ in range(queries):
                    started = time.perf_counter()
                    await rov.depth_cm()
                    timings.append(time.perf_counter() - started)
                return timings
        return asyncio.run(main())
    return run


def _run_way(way: Callable[[Sim, int, int], Timings], sim: Sim, queries: int,
             baud: int) -> Timings:
    for attempt in range(CONNECT_ATTEMPTS):
        try:
            return way(sim, queries, baud)
        except (ConnectionError, serial.SerialException):
            if attempt == CONNECT_ATTEMPTS - 1:
                raise
            time.sleep(RETRY_AFTER_S)  # refused as busy: the previous client is still leaving
    raise AssertionError("unreachable")


def _time_queries(queries: int, query: Callable[[], object]) -> Timings:
    for _ in range(WARM_UP_QUERIES):
        query()
    timings = []
    for _ in range(queries):
        started = time.perf_counter()
        query()
        timings.append(time.perf_counter() - started)
    return timings


WAYS: dict[str, list[tuple[str, Callable[[Sim, int, int], Timings]]]] = {
    "pty": [
        ("raw select + read", raw_pty),
        ("pyserial read_until", pyserial_read_until("{sim.pty_path}")),
        ("rovlink.connect", driver_blocking("{sim.pty_path}")),
        ("rovlink.aio.connect", driver_asyncio("{sim.pty_path}")),
    ],
    "tcp": [
        ("raw select + recv", raw_tcp),
        ("pyserial read_until", pyserial_read_until("socket://{sim.tcp_host}:{sim.tcp_port}")),
        ("rovlink.connect", driver_blocking("{sim.tcp_url}")),
        ("rovlink.aio.connect", driver_asyncio("{sim.tcp_url}")),
    ],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--queries", type=int, default=500, help="queries per way per round")
    parser.add_argument("--rounds", type=int, default=20)
    parser.add_argument("--baud", type=int, default=None,
                        help="pace the simulator's line at this rate (default: unpaced)")
    arguments = parser.parse_args()
    baud = arguments.baud or 115200
    options = ["--baud", str(arguments.baud)] if arguments.baud else []
    with running_sim(*options) as sim:
        for transport, ways in WAYS.items():
            samples: dict[str, Timings] = {name: [] for name, _ in ways}
            ratios: dict[str, list[float]] = {name: [] for name, _ in ways}
            for _ in range(arguments.rounds):
                medians = {}
                for name, way in ways:
                    timings = _run_way(way, sim, arguments.queries, baud)
                    samples[name] += timings
                    medians[name] = statistics.median(timings)
                for name, _ in ways:
                    ratios[name].append(medians[name] / medians[ways[0][0]])
            pacing = f"{arguments.baud} baud" if arguments.baud else "unpaced"
            print(f"\n{transport} ({pacing}), {arguments.rounds} × {arguments.queries} queries")
            print(f"{'way':<22}{'median µs':>11}{'p90 µs':>9}{'× raw':>8}")
            for name, _ in ways:
                timings = sorted(samples[name])
                median = statistics.median(timings)
                p90 = timings[int(len(timings) * 0.9)]
                print(f"{name:<22}{median * 1e6:>11.0f}{p90 * 1e6:>9.0f}"
                      f"{statistics.median(ratios[name]):>8.2f}")


if __name__ == "__main__":
    main()
