"""Query reply latency of ``rovlink sim --pty``, side by side with a bare PTY echo.

Both peers are Python processes serving a pseudo-terminal; the echo peer only copies bytes back,
so it measures what the PTY and a process wake-up cost by themselves. The two are queried in
alternation, in the same run, and the time from writing a query to reading the last byte of its
reply is recorded. P19 asks for a reply within 5 ms.

    PYTHONPATH=src python bench/latency.py [--count 1000] [--baud 115200]
"""

from __future__ import annotations

import argparse
import os
import re
import select
import statistics
import subprocess
import sys
import time
import tty
from collections.abc import Iterator
from contextlib import contextmanager

P19_LIMIT_MS = 5.0


def serve_echo() -> None:
    """The echo peer: a raw PTY whose master copies every byte back."""
    master_fd, slave_fd = os.openpty()
    tty.setraw(slave_fd)
    print(f"echo ready: pty {os.ttyname(slave_fd)}", flush=True)
    while True:
        select.select([master_fd], [], [])
        data = os.read(master_fd, 4096)
        while data:
            data = data[os.write(master_fd, data) :]


@contextmanager
def _peer(command: list[str], pattern: str) -> Iterator[str]:
    environment = dict(os.environ)
    process = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=environment
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        match = re.search(pattern, line)
        if not match:
            raise RuntimeError(f"unexpected first line from {command[:3]}: {line!r}")
        yield match.group(1)
    finally:
        process.terminate()
        process.wait(timeout=10)


def _open_raw(path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    return fd


def _round_trip_ms(
    fd: int, request: bytes, expect_ends: int, reply_length: int | None
) -> tuple[float, float]:
    """Write ``request``; wait for ``expect_ends`` frame ends (or ``reply_length`` bytes).

    Returns the milliseconds to the first and to the last byte of the reply.
    """
    received = b""
    first_ns = 0
    started = time.perf_counter_ns()
    os.write(fd, request)
    while True:
        select.select([fd], [], [], 1.0)
        received += os.read(fd, 4096)
        if not first_ns and received:
            first_ns = time.perf_counter_ns()
        if reply_length is not None and len(received) >= reply_length:
            break
        if reply_length is None and received.count(b"!") >= expect_ends:
            break
    return (first_ns - started) / 1e6, (time.perf_counter_ns() - started) / 1e6


def _drain(fd: int) -> None:
    while select.select([fd], [], [], 0.05)[0]:
        os.read(fd, 4096)


def _summary(name: str, samples: list[float]) -> str:
    ordered = sorted(samples)
    p99 = ordered[min(len(ordered) - 1, round(0.99 * len(ordered)))]
    return (
        f"  {name:<22} median {statistics.median(ordered):6.3f} ms  "
        f"p90 {ordered[int(0.9 * len(ordered))]:6.3f}  p99 {p99:6.3f}  "
        f"max {ordered[-1]:6.3f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--count", type=int, default=1000, help="round trips of each kind")
    parser.add_argument("--baud", type=int, help="pace the simulator's line at this rate")
    parser.add_argument("--echo-server", action="store_true", help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    if arguments.echo_server:
        serve_echo()
        return

    sim_command = [
        sys.executable,
        "-c",
        "from rovlink.cli import main; main()",
        "sim",
        "--pty",
        "--seed",
        "1",
        *(["--baud", str(arguments.baud)] if arguments.baud else []),
    ]
    echo_command = [sys.executable, os.path.abspath(__file__), "--echo-server"]
    samples: dict[str, list[float]] = {"sim #qd!": [], "sim #qsa!": [], "echo (4 bytes)": []}
    first_byte_ms: list[float] = []
    with (
        _peer(sim_command, r"pty (\S+?)[,\s]") as sim_path,
        _peer(echo_command, r"pty (\S+)") as echo_path,
    ):
        sim_fd, echo_fd = _open_raw(sim_path), _open_raw(echo_path)
        _drain(sim_fd)
        for index in range(arguments.count):
            trips = [
                ("sim #qd!", sim_fd, b"#qd!", 1, None),
                ("sim #qsa!", sim_fd, b"#qsa!", 6, None),
                ("echo (4 bytes)", echo_fd, b"#qd!", 0, 4),
            ]
            if index % 2:
                trips.reverse()  # neither peer always goes first
            for name, fd, request, ends, length in trips:
                first_ms, last_ms = _round_trip_ms(fd, request, ends, length)
                samples[name].append(last_ms)
                if name.startswith("sim"):
                    first_byte_ms.append(first_ms)
        os.close(sim_fd)
        os.close(echo_fd)

    pacing = f"simulator paced at {arguments.baud} baud" if arguments.baud else "unpaced PTYs"
    print(
        f"{arguments.count} round trips each, {pacing}, alternating peers "
        "(write of the query to the last byte of the reply):"
    )
    for name, values in samples.items():
        print(_summary(name, values))
    ratio = statistics.median(samples["sim #qd!"]) / statistics.median(samples["echo (4 bytes)"])
    worst = max(first_byte_ms)
    print(f"  median ratio sim #qd! / echo: {ratio:.2f}")
    # P19 counts from the query's arrival to the answer: the first reply byte bounds it from
    # above (it also includes the query's own time on the line).
    print(
        f"  first reply byte: median {statistics.median(first_byte_ms):.3f} ms, slowest "
        f"{worst:.3f} ms; P19 limit {P19_LIMIT_MS:g} ms: "
        f"{'met' if worst <= P19_LIMIT_MS else 'MISSED'}"
    )


if __name__ == "__main__":
    main()
