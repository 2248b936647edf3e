"""How late a ``#stop!`` reaches the controller after a burst of motion on a slow serial line.

    PYTHONPATH=src python bench/stop_latency.py [--baud 9600] [--burst-s 1.0] [--rounds 5]

A simulated controller paced at ``--baud`` serves a pseudo-terminal; a program sends ``move``
frames back to back for ``--burst-s`` seconds, then ``#stop!``, and the time from the stop to the
controller seeing it is recorded. Two senders, in alternation in the same run:

* raw pyserial: ``port.write`` of each frame, then of ``#stop!`` — what a program that writes
  to the port itself gets: the frames the port's buffers took are all ahead of the stop;
* ``rovlink.connect(url).move(...)`` then ``stop()``: the client lets at most 20 ms of the line
  queue ahead of a frame other than ``#stop!`` (docs/driver.md, *A slow line*).

The line's buffers are the simulator's 4 KB (a serial driver's) and the pseudo-terminal's own.
"""

from __future__ import annotations

import argparse
import statistics
import threading
import time
from collections.abc import Callable, Hashable, Iterator
from contextlib import contextmanager

import serial

import rovlink
from rovlink.sim.server import SimServer

MOVE = b"#th.90.30!"
STOP = b"#stop!"


class _WatchedSim:
    """The simulated controller at ``baud`` on a PTY, and when it saw the latest ``#stop!``."""

    def __init__(self, baud: int) -> None:
        self.server = SimServer(seed=1, baud=baud)
        self.path = self.server.open_pty()
        self.stop_seen = threading.Event()
        self.stop_seen_at_s = 0.0
        received = bytearray()
        receive = self.server.robot.receive

        def watched(data: bytes, line: Hashable = None) -> None:
            received.extend(data)
            if STOP in received[-len(data) - len(STOP) :]:
                self.stop_seen_at_s = time.monotonic()
                self.stop_seen.set()
                received.clear()
            del received[: -len(STOP)]
            receive(data, line)

        self.server.robot.receive = watched  # type: ignore[method-assign]
        self._ending = threading.Event()
        self._thread = threading.Thread(target=self.server.serve, args=(self._ending.is_set,))
        self._thread.start()

    def close(self) -> None:
        self._ending.set()
        self._thread.join()
        self.server.close()


@contextmanager
def _sim(baud: int) -> Iterator[_WatchedSim]:
    sim = _WatchedSim(baud)
    try:
        yield sim
    finally:
        sim.close()


def _raw_burst(sim: _WatchedSim, baud: int, burst_s: float) -> float:
    with serial.Serial(sim.path, baud, write_timeout=60) as port:
        end_s = time.monotonic() + burst_s
        while time.monotonic() < end_s:
            port.write(MOVE)
        sim.stop_seen.clear()
        stopped_at_s = time.monotonic()
        port.write(STOP)
        sim.stop_seen.wait(120)
        return sim.stop_seen_at_s - stopped_at_s


def _client_burst(sim: _WatchedSim, baud: int, burst_s: float) -> float:
    with rovlink.connect(f"{sim.path}?baudrate={baud}", keepalive=None) as rov:
        rov.start()
        end_s = time.monotonic() + burst_s
        while time.monotonic() < end_s:
            rov.move(90, 30)
        sim.stop_seen.clear()
        stopped_at_s = time.monotonic()
        rov.stop()
        sim.stop_seen.wait(120)
        return sim.stop_seen_at_s - stopped_at_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baud", type=int, default=9600)
    parser.add_argument("--burst-s", type=float, default=1.0)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    ways: dict[str, Callable[[_WatchedSim, int, float], float]] = {
        "raw pyserial": _raw_burst,
        "rovlink.connect": _client_burst,
    }
    latencies_s: dict[str, list[float]] = {name: [] for name in ways}
    for _ in range(args.rounds):
        for name, burst in ways.items():
            with _sim(args.baud) as sim:  # (a fresh line each time: nothing left queued)
                latencies_s[name].append(burst(sim, args.baud, args.burst_s))
    burst = f"{args.burst_s:g} s of moves at {args.baud} baud"
    print(f"#stop! latency after {burst}, {args.rounds} rounds")
    for name, values in latencies_s.items():
        print(
            f"  {name:16s} median {statistics.median(values) * 1e3:9.1f} ms"
            f"   max {max(values) * 1e3:9.1f} ms"
        )
    ratio = statistics.median(latencies_s["rovlink.connect"]) / statistics.median(
        latencies_s["raw pyserial"]
    )
    print(f"  rovlink / raw: {ratio:.3f}")


if __name__ == "__main__":
    main()
