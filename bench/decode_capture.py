"""``rovlink decode --stats --checksum`` on a checksummed capture, against a pynmea2 script.

    python bench/decode_capture.py [--frames 400000] [--repeat 5] [--stream session|all-new]

Builds a capture of ``--frames`` checksummed frames (CRC-8) and an NMEA log of as many sentences,
then times both tools as whole processes, start-up included, as a person runs them:
``rovlink decode --stats --checksum CAPTURE`` and a Python script that reads the log line by line
and ``pynmea2.parse``-s every sentence. Runs alternate between the two; the best and the median of
``--repeat`` runs of each are printed with the ratio, and the CPU time of each process beside.

Streams: "session" (the default) is what a log of a working robot holds: a host polling ``#qsa!``
and the six replies of sensors that drift as a real robot's do, a command with new values after
every poll (``th``, ``mvd``, ``mvs``), and a debug line now and then; "all-new" is the decoder's
worst case of ``bench/codec.py``, where no frame repeats within twice the decoder's cache.
Target: rovlink at least 2× as fast as the pynmea2 script.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from codec import (
    NMEA_BODIES,
    all_new_messages,
    nmea_sentence,
    stream_of,
    telemetry_messages,
)
from rovlink.protocol import Command, Message

TARGET_RATIO = 2.0
DEBUG_LINE = b"pid out=+12 depth=101 target=100\r\n"

NMEA_SCRIPT = """
import sys, pynmea2
count = 0
with open(sys.argv[1], encoding="ascii") as log:
    for line in log:
        pynmea2.parse(line.strip())
        count += 1
print(count)
"""


def session_messages(frames: int, seed: int) -> list[Message]:
    """``frames`` messages of a working session: telemetry polls, each followed by a command."""
    rng = random.Random(seed)
    telemetry = telemetry_messages(frames // 8 + 1, seed)
    messages: list[Message] = []
    for start in range(0, len(telemetry), 7):
        messages += telemetry[start : start + 7]
        messages.append(
            rng.choice(
                [
                    Command("th", (rng.randint(0, 360), rng.randint(0, 100))),
                    Command("mvd", (rng.randint(0, 9999),)),
                    Command("mvs", (rng.randint(-100, 100),)),
                ]
            )
        )
    return messages[:frames]


def make_capture(messages: list[Message], seed: int) -> bytes:
    """The checksummed frames of ``messages``, with a debug line about every 200 frames."""
    rng = random.Random(seed)
    pieces: list[bytes] = []
    start = 0
    while start < len(messages):
        stop = start + rng.randint(100, 300)
        pieces.append(stream_of(messages[start:stop], checksum=True))
        pieces.append(DEBUG_LINE)
        start = stop
    return b"".join(pieces)


def make_nmea_log(sentences: int, seed: int) -> str:
    rng = random.Random(seed)
    return "".join(nmea_sentence(rng.choice(NMEA_BODIES)) + "\n" for _ in range(sentences))


def rovlink_command() -> list[str]:
    """``rovlink`` as installed beside this Python, else ``python -m rovlink``."""
    script = Path(sys.executable).with_name("rovlink")
    if script.exists() or shutil.which("rovlink") == str(script):
        return [str(script)]
    return [sys.executable, "-m", "rovlink"]


def timed(command: list[str]) -> tuple[float, float, str]:
    """Wall-clock and CPU seconds of one whole process, and its standard output."""
    cpu_before = os.times()
    started = time.perf_counter()
    output = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    wall = time.perf_counter() - started
    cpu_after = os.times()
    cpu = (
        cpu_after.children_user
        - cpu_before.children_user
        + cpu_after.children_system
        - cpu_before.children_system
    )
    return wall, cpu, output


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=400_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--stream", choices=("session", "all-new"), default="session")
    args = parser.parse_args()
    frames: int = args.frames
    if args.stream == "session":
        messages = session_messages(frames, seed=1)
    else:
        messages = all_new_messages(frames, seed=4)
    with tempfile.TemporaryDirectory(prefix="rovlink-bench-") as folder:
        capture = Path(folder) / "capture.bin"
        capture.write_bytes(make_capture(messages, seed=2))
        nmea_log = Path(folder) / "log.nmea"
        nmea_log.write_text(make_nmea_log(frames, seed=3), encoding="ascii")
        script = Path(folder) / "nmea_peer.py"
        script.write_text(NMEA_SCRIPT, encoding="utf-8")
        rovlink = [*rovlink_command(), "decode", "--stats", "--checksum", str(capture)]
        nmea = [sys.executable, str(script), str(nmea_log)]
        runs: dict[str, list[tuple[float, float]]] = {"rovlink": [], "pynmea2": []}
        for _ in range(args.repeat):
            wall, cpu, summary = timed(rovlink)
            counts = json.loads(summary)["events"]
            # A fast wrong decoder is no result: every frame must have come out, and no error.
            if counts.get("frame") != frames or counts.get("error"):
                raise AssertionError(f"rovlink decode counted {counts}, expected {frames} frames")
            runs["rovlink"].append((wall, cpu))
            wall, cpu, count = timed(nmea)
            if int(count) != frames:
                raise AssertionError(f"the pynmea2 script parsed {count}, expected {frames}")
            runs["pynmea2"].append((wall, cpu))
        sizes = {"rovlink": capture.stat().st_size, "pynmea2": nmea_log.stat().st_size}

    print(
        f"{frames:,} frames / sentences, stream {args.stream}, {args.repeat} runs each, "
        f"Python {sys.version.split()[0]}"
    )
    print(f"{'process':<36}{'best s':>8}{'median s':>10}{'CPU s':>8}{'MB':>7}")
    labels = {
        "rovlink": "rovlink decode --stats --checksum",
        "pynmea2": "pynmea2.parse script, line by line",
    }
    for name, timings in runs.items():
        walls = [wall for wall, _ in timings]
        cpu = statistics.median(cpu for _, cpu in timings)
        print(
            f"{labels[name]:<36}{min(walls):>8.3f}{statistics.median(walls):>10.3f}"
            f"{cpu:>8.3f}{sizes[name] / 1e6:>7.1f}"
        )
    best = min(w for w, _ in runs["pynmea2"]) / min(w for w, _ in runs["rovlink"])
    median = statistics.median(w for w, _ in runs["pynmea2"]) / statistics.median(
        w for w, _ in runs["rovlink"]
    )
    print(
        f"rovlink is {best:.2f}x as fast as pynmea2 (best of each), {median:.2f}x (medians); "
        f"target ≥ {TARGET_RATIO:.1f}x: {'met' if best >= TARGET_RATIO else 'NOT met'}"
    )


if __name__ == "__main__":
    main()
