"""Pipelined ``sensors()`` polling through the asyncio client, as a share of the line rate.

    python bench/driver_pipeline.py [--seconds 5] [--baud 115200] [--rounds 3]

Starts ``rovlink sim --pty --baud 115200``: the simulator paces its pseudo-terminal like a real
8N1 serial line, ten bits per byte. Each ``#qsa!`` is answered by six frames, about 50 bytes, so
the line cannot carry more than ``baud / 10 / reply_bytes`` readings per second — the bound.

Measured, with the reply size taken from the bytes actually received:

* ``telemetry(None)`` — the asyncio client with up to 8 polls in flight (the default);
* the same with one poll in flight (``max_in_flight=1``): a round trip per reading;
* a loop of blocking ``sensors()`` calls, for comparison.

Each way runs with checksums off and on (on adds two characters per frame).
"""

from __future__ import annotations

import argparse
import asyncio
import statistics
import time
from collections.abc import Callable

import rovlink
import rovlink.aio
from driver_sim import Sim, running_sim
from rovlink.client import LinkCounters

WARM_UP_S = 0.3


async def _async_polling(
    sim: Sim, seconds: float, checksum: bool, baud: int, max_in_flight: int
) -> tuple[int, float, LinkCounters]:
    async with rovlink.aio.connect(
        sim.pty_path, checksum=checksum, baudrate=baud, max_in_flight=max_in_flight
    ) as rov:
        readings = 0
        started = time.perf_counter()
        measured_from = None
        before = rov.counters
        async for _ in rov.telemetry(None):
            now = time.perf_counter()
            if measured_from is None:
                if now - started >= WARM_UP_S:  # the clock starts at this reading
                    measured_from, before = now, rov.counters
                continue
            readings += 1
            if now - measured_from >= seconds:
                break
        elapsed = time.perf_counter() - (measured_from or started)
        after = rov.counters
    delta = LinkCounters(
        **{name: after.as_dict()[name] - before.as_dict()[name] for name in after.as_dict()}
    )
    return readings, elapsed, delta


def pipelined(
    max_in_flight: int,
) -> Callable[[Sim, float, bool, int], tuple[int, float, LinkCounters]]:
    def run(
        sim: Sim,
        seconds: float,
        checksum: bool,
        baud: int,
    ) -> tuple[int, float, LinkCounters]:
        return asyncio.run(_async_polling(sim, seconds, checksum, baud, max_in_flight))

    return run


def blocking(
    sim: Sim,
    seconds: float,
    checksum: bool,
    baud: int,
) -> tuple[int, float, LinkCounters]:
    with rovlink.connect(sim.pty_path, checksum=checksum, baudrate=baud) as rov:
        deadline = time.perf_counter() + WARM_UP_S
        while time.perf_counter() < deadline:
            rov.sensors()
        before = rov.counters
        readings = 0
        started = time.perf_counter()
        while time.perf_counter() - started < seconds:
            rov.sensors()
            readings += 1
        elapsed = time.perf_counter() - started
        after = rov.counters
    delta = LinkCounters(
        **{name: after.as_dict()[name] - before.as_dict()[name] for name in after.as_dict()}
    )
    return readings, elapsed, delta


WAYS = [
    ("aio telemetry, 8 in flight", pipelined(8)),
    ("aio telemetry, 1 in flight", pipelined(1)),
    ("blocking sensors() loop", blocking),
]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="measured time per run")
    parser.add_argument("--baud", type=int, default=115200)
    parser.add_argument("--rounds", type=int, default=3)
    arguments = parser.parse_args()
    line_bytes_per_s = arguments.baud / 10
    with running_sim("--baud", str(arguments.baud), "--seed", "1") as sim:
        for checksum in (False, True):
            shares: dict[str, list[tuple[float, float, float]]] = {name: [] for name, _ in WAYS}
            for _ in range(arguments.rounds):
                for name, way in WAYS:
                    readings, elapsed, counters = way(
                        sim, arguments.seconds, checksum, arguments.baud
                    )
                    reply_bytes = counters.bytes_received / max(counters.replies, 1)
                    rate = readings / elapsed
                    bound = line_bytes_per_s / reply_bytes
                    shares[name].append((rate, bound, reply_bytes))
            mode = "checksums on" if checksum else "checksums off"
            print(
                f"\n{arguments.baud} baud, {mode}, {arguments.rounds} × {arguments.seconds:g} s"
                " (median of the rounds)"
            )
            print(f"{'way':<28}{'readings/s':>11}{'bound/s':>9}{'bytes/reply':>12}{'share':>8}")
            for name, _ in WAYS:
                rate = statistics.median(r for r, _, _ in shares[name])
                bound = statistics.median(b for _, b, _ in shares[name])
                size = statistics.median(s for _, _, s in shares[name])
                print(f"{name:<28}{rate:>11.1f}{bound:>9.1f}{size:>12.1f}{rate / bound:>8.1%}")


if __name__ == "__main__":
    main()
