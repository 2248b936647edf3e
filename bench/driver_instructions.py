"""Query round trip: the host's user-space instructions per query, counted by valgrind.

    python bench/driver_instructions.py [--queries 2000] [--checksum] [--ways NAME ...]

The same ways as ``bench/driver_cpu.py`` (raw socket, raw + session only, raw + lock, queue,
int, ``rovlink.connect``, raw asyncio streams, ``rovlink.aio.connect``), each run ``#qd!`` →
``$qd.N!`` against ``fast_controller.c`` in a process of its own under ``valgrind
--tool=callgrind``, which counts the instructions the process executes (its own and its
libraries', not the kernel's).

CPU time per query (``driver_cpu.py``) is the figure with a target, but on a shared virtual
machine it moves by ±10 % from run to run, and more for asyncio: too much to tell whether a
change to the client's code made it cheaper. The instruction count does not move: it is the same
for the same code, interpreter and inputs whatever else the machine does, so a change of a few
hundred instructions per query shows. What it does not show is what an instruction costs after
each wait for a reply, when the caches are cold (``driver_cpu.py`` measures that).

Each way runs twice, with ``WARM_UP_QUERIES`` and then ``WARM_UP_QUERIES + --queries`` queries;
the difference, divided by ``--queries``, is the count per query, without start-up and
connection. The warm-up is 10,200 queries so that the controller's counting replies have gone
round once (``$qd.0!`` to ``$qd.9999!``) and the decoder's tables of numbers are filled, as in
``driver_cpu.py``'s run. Hash randomisation is fixed (``PYTHONHASHSEED=0``) so that two runs of
the same code count the same. Under valgrind a query takes about 50 times as long: the default
run takes about two minutes.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Awaitable, Callable

import rovlink
import rovlink.aio
from driver_cpu import (
    LEAST_CLIENT,
    PEERS,
    SESSION_FLOOR,
    WAYS,
    raw_socket_query,
    with_least_client,
    with_session_bookkeeping,
)
from fast_controller import NoCompilerError, running_fast_controller
from rovlink.protocol import Command, encode

WARM_UP_QUERIES = 10_200
_COLLECTED = re.compile(r"Collected : (\d+)")


class NoValgrindError(RuntimeError):
    """valgrind is not installed: nothing can count the instructions."""


def run_way(way: str, url: str, queries: int, checksum: bool) -> None:
    """Make ``queries`` queries one way (in the process valgrind counts)."""
    host, port = url.removeprefix("socket://").rsplit(":", 1)
    query = encode(Command("qd"), checksum="crc8" if checksum else None)
    if way in ("raw socket", SESSION_FLOOR, LEAST_CLIENT):
        sock, raw_round_trip = raw_socket_query(host, int(port), query)
        round_trip: Callable[[], object] = raw_round_trip
        if way == SESSION_FLOOR:
            round_trip = with_session_bookkeeping(raw_round_trip, checksum)
        elif way == LEAST_CLIENT:
            round_trip = with_least_client(raw_round_trip, checksum)
        with sock:
            for _ in range(queries):
                round_trip()
    elif way == "rovlink.connect":
        with rovlink.connect(url, keepalive=None, checksum=checksum) as rov:
            for _ in range(queries):
                rov.depth_cm()
    else:
        asyncio.run(_run_async_way(way, url, queries, checksum, query))


async def _run_async_way(way: str, url: str, queries: int, checksum: bool, query: bytes) -> None:
    if way == "rovlink.aio.connect":
        async with rovlink.aio.connect(url, keepalive=None, checksum=checksum) as rov:
            await _repeat(rov.depth_cm, queries)
        return
    host, port = url.removeprefix("socket://").rsplit(":", 1)
    reader, writer = await asyncio.open_connection(host, int(port))
    if checksum:
        writer.write(b"#crcon!")

    async def raw_query() -> bytes:
        writer.write(query)
        return await reader.readuntil(b"!")

    try:
        await _repeat(raw_query, queries)
    finally:
        writer.close()
        await writer.wait_closed()


async def _repeat(query: Callable[[], Awaitable[object]], queries: int) -> None:
    for _ in range(queries):
        await query()


def instructions(way: str, url: str, queries: int, checksum: bool) -> int:
    """Instructions a process of this way executes, start to end, for ``queries`` queries."""
    command = [
        "valgrind",
        "--tool=callgrind",
        "--callgrind-out-file=/dev/null",
        sys.executable,
        __file__,
        "--run-way",
        way,
        "--url",
        url,
        "--queries",
        str(queries),
        *(["--checksum"] if checksum else []),
    ]
    environment = {**os.environ, "PYTHONHASHSEED": "0"}
    result = subprocess.run(command, capture_output=True, text=True, env=environment, check=False)
    collected = _COLLECTED.search(result.stderr)
    if result.returncode != 0 or collected is None:
        raise RuntimeError(f"{way} under valgrind failed ({result.returncode}):\n{result.stderr}")
    return int(collected.group(1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--queries", type=int, default=2000, help="queries counted per way")
    parser.add_argument("--checksum", action="store_true", help="CRC-8 checksum mode on")
    parser.add_argument("--ways", nargs="+", choices=WAYS, default=list(WAYS), metavar="WAY")
    parser.add_argument("--run-way", choices=WAYS, help=argparse.SUPPRESS)
    parser.add_argument("--url", help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    if arguments.run_way:  # the process valgrind counts
        run_way(arguments.run_way, arguments.url, arguments.queries, arguments.checksum)
        return 0
    try:
        if shutil.which("valgrind") is None:
            raise NoValgrindError(
                "valgrind not found: install it (e.g. apt-get install valgrind) to count the "
                "instructions"
            )
        per_query: dict[str, float] = {}
        with running_fast_controller() as controller:
            for way in arguments.ways:
                counts = [
                    instructions(way, controller.url, queries, arguments.checksum)
                    for queries in (WARM_UP_QUERIES, WARM_UP_QUERIES + arguments.queries)
                ]
                per_query[way] = (counts[1] - counts[0]) / arguments.queries
    except (NoCompilerError, NoValgrindError) as error:
        print(f"driver_instructions: {error}", file=sys.stderr)
        return 2

    print(
        f"{arguments.queries} queries per way after {WARM_UP_QUERIES:,} of warm-up, checksums "
        f"{'on' if arguments.checksum else 'off'}, Python {sys.version.split()[0]}"
    )
    print(f"{'way':<22}{'instructions/query':>20}{'× peer':>9}{'more per query':>16}")
    peers = {**PEERS, SESSION_FLOOR: "raw socket", LEAST_CLIENT: "raw socket"}
    for way, count in per_query.items():
        line = f"{way:<22}{count:>20,.0f}"
        peer = per_query.get(peers.get(way, ""))
        if peer:
            line += f"{count / peer:>9.2f}{count - peer:>+16,.0f}"
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
