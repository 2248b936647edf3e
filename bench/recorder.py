"""The flight recorder's cost and capacity, measured against the same driver in the same run.

    python bench/recorder.py [--rounds 7] [--block 300] [--hour-s 3600] [--format .mcap]

1. Round trip: ``depth_cm()`` through the blocking driver, recording off and recording on to a
   temporary ``.mcap``, in alternating blocks so that load from elsewhere hits both alike,
   against two controllers: ``rovlink sim --tcp`` (the simulated controller in its own process,
   a realistic round trip) and ``fast_controller.c`` (a C controller that answers at once: the
   worst case, where nothing but the host's own work is timed). Printed: the wall-clock and CPU
   time per query each way and the ratio on/off (target: ≤ 1.05).
2. A saturated 1 Mbaud line: 100 kB/s of reply frames handed to the recorder for ten seconds in
   real time. Printed: items dropped (target 0), the deepest the queue got, the file's size.
3. An hour of 10 Hz telemetry (``qsa`` every 100 ms, every byte both ways, the depth changing
   at every reply), fed as fast as the writer takes it, each format in a fresh process.
   Printed: the file's size per format and the process's peak memory at 10 % and at 100 % of
   the hour (flat: the recorder keeps nothing but its queue).
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager

import rovlink
from fast_controller import NoCompilerError, running_fast_controller
from rovlink.client.events import BytesReceived, BytesSent, ReplyReceived
from rovlink.protocol import Command, Response
from rovlink.recorder import Recorder

TARGET_RATIO = 1.05
_QSA = Command("qsa")
_QSA_BYTES = b"#qsa!"
_REPLY_BYTES = b"$qr.512!$q.l.0!$qro.-3!$qpi.+2!$qhe.271!"
_REPLIES = (
    Response("qr", (512,)),
    Response("q.l", (0,)),
    Response("qro", (-3,)),
    Response("qpi", (2,)),
    Response("qhe", (271,)),
)


def _block(rov: rovlink.Client, count: int) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(count):
        rov.depth_cm()
    return time.perf_counter() - wall, time.process_time() - cpu


@contextmanager
def running_sim_tcp() -> Iterator[str]:
    """``rovlink sim --tcp`` in its own process; its URL."""
    process = subprocess.Popen(
        [sys.executable, "-m", "rovlink", "sim", "--tcp", "127.0.0.1:0", "--watchdog", "0"],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert process.stdout is not None
        found = re.search(r"tcp ([^\s,]+):(\d+)", process.stdout.readline())
        assert found, "rovlink sim printed no TCP address"
        yield f"socket://{found.group(1)}:{found.group(2)}"
    finally:
        process.terminate()
        process.wait()


def round_trip(urls: tuple[str, str], label: str, rounds: int, block: int, directory: str) -> None:
    """Part 1: the driver's round trip with recording off and on (a controller each)."""
    recorder = Recorder(os.path.join(directory, "round-trip.mcap"), url=urls[1])
    plain = rovlink.connect(urls[0], keepalive=None, motion_timeout=None)
    recorded = rovlink.connect(
        urls[1], keepalive=None, motion_timeout=None, on_event=recorder.on_event
    )
    with plain, recorded:
        _block(plain, 200)
        _block(recorded, 200)
        off: list[tuple[float, float]] = []
        on: list[tuple[float, float]] = []
        for _ in range(rounds):
            off.append(_block(plain, block))
            on.append(_block(recorded, block))
    recorder.close()
    per_query = 1e6 / block
    wall_off = statistics.median(w for w, _ in off) * per_query
    wall_on = statistics.median(w for w, _ in on) * per_query
    cpu_off = statistics.median(c for _, c in off) * per_query
    cpu_on = statistics.median(c for _, c in on) * per_query
    ratio = wall_on / wall_off
    verdict = "met" if ratio <= TARGET_RATIO else "NOT met"
    print(f"{label}:")
    print(f"  recording off: {wall_off:7.1f} µs wall, {cpu_off:6.1f} µs CPU per query")
    print(f"  recording on:  {wall_on:7.1f} µs wall, {cpu_on:6.1f} µs CPU per query")
    print(
        f"  ratio on/off: {ratio:.3f} wall, {cpu_on / cpu_off:.3f} CPU "
        f"(target ≤ {TARGET_RATIO:.2f}: {verdict}; {recorder.dropped} dropped)"
    )


def saturated_line(directory: str, seconds: float = 10.0) -> None:
    """Part 2: 100 kB/s of frames in real time."""
    recorder = Recorder(os.path.join(directory, "saturated.mcap"))
    chunk = b"$qd.1234!" * 11  # 99 bytes, as a driver reads them
    chunks_per_s = 100_000 / len(chunk)
    deepest = 0
    started = time.monotonic()
    sent = 0
    while (now := time.monotonic()) - started < seconds:
        due = int((now - started) * chunks_per_s)
        while sent < due:
            recorder.on_event(BytesReceived(time.monotonic(), chunk))
            sent += 1
        deepest = max(deepest, len(recorder._queue))
        time.sleep(0.001)
    recorder.close()
    size = sum(os.path.getsize(path) for path in recorder.paths)
    print(
        f"saturated 1 Mbaud line: {sent * len(chunk) / seconds / 1000:.0f} kB/s for "
        f"{seconds:g} s, {recorder.dropped} dropped, deepest queue {deepest} items "
        f"(limit {recorder._queue_limit}), file {size / 1e6:.1f} MB"
    )


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def hour_of_telemetry(directory: str, hour_s: float, suffix: str) -> None:
    """Part 3: an hour of 10 Hz qsa, fed as fast as the writer takes it."""
    path = os.path.join(directory, f"hour{suffix}")
    recorder = Recorder(path)
    polls = int(hour_s * 10)
    checkpoints = {polls // 10: 0.0, polls: 0.0}
    for index in range(1, polls + 1):
        at_s = index * 0.1
        recorder.on_event(BytesSent(at_s, _QSA_BYTES, _QSA))
        depth_cm = index % 500
        reply = b"$qd.%d!" % depth_cm + _REPLY_BYTES
        recorder.on_event(BytesReceived(at_s + 0.002, reply))
        recorder.on_event(
            ReplyReceived(at_s + 0.002, _QSA, (Response("qd", (depth_cm,)), *_REPLIES))
        )
        while len(recorder._queue) > 1_000:  # a real link hands over 30 items a second
            time.sleep(0.01)
        if index in checkpoints:
            checkpoints[index] = _peak_rss_mb()
    recorder.close()
    size = os.path.getsize(path)
    first, last = checkpoints.values()
    print(
        f"{hour_s / 3600:g} h of 10 Hz qsa with every byte, {suffix}: {size / 1e6:.1f} MB "
        f"({recorder.entries_written} entries); peak memory {first:.0f} MB at 10 %, "
        f"{last:.0f} MB at 100 %"
    )


def main() -> int:
    """Run the three parts and print their figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--block", type=int, default=300)
    parser.add_argument("--hour-s", type=float, default=3600.0)
    parser.add_argument("--format", action="append", dest="formats")
    parser.add_argument("--only-hour", action="store_true", help=argparse.SUPPRESS)
    arguments = parser.parse_args()
    formats = arguments.formats or [".mcap", ".jsonl", ".csv", ".bin"]
    with tempfile.TemporaryDirectory() as directory:
        if arguments.only_hour:
            hour_of_telemetry(directory, arguments.hour_s, formats[0])
            return 0
        with running_sim_tcp() as first, running_sim_tcp() as second:
            label = "round trip, rovlink sim --tcp (one process per client)"
            round_trip((first, second), label, arguments.rounds, 100, directory)
        try:
            with running_fast_controller() as controller:
                label = "round trip, instant C controller"
                urls = (controller.url, controller.url)  # it serves each connection alike
                round_trip(urls, label, arguments.rounds, arguments.block, directory)
        except NoCompilerError as error:
            print(f"recorder: {error}", file=sys.stderr)
            return 2
        saturated_line(directory)
    for suffix in formats:  # each in a fresh process: peak memory is per process
        command = [sys.executable, __file__, "--only-hour", "--format", suffix]
        subprocess.run([*command, "--hour-s", str(arguments.hour_s)], check=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
