"""``rovlink decode --stats`` on a 10 MB capture, against a pynmea2 script on a log of equal size.

    python bench/decode_capture.py [--megabytes 10]

The capture mixes what a serial log holds: the host's queries and commands, the controller's
replies, debug lines and line noise. Both tools run as subprocesses, start-up included, as a person
would run them; the NMEA peer parses every line of an NMEA log of the same size.
"""

from __future__ import annotations

import argparse
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from codec import NMEA_BODIES, nmea_sentence, stream_of, telemetry_messages
from rovlink.protocol import Command, encode

NMEA_SCRIPT = """
import sys, pynmea2
count = 0
with open(sys.argv[1], encoding="ascii") as log:
    for line in log:
        pynmea2.parse(line.strip())
        count += 1
print(count)
"""


def make_capture(size_bytes: int, seed: int) -> bytes:
    """Telemetry with commands, debug lines and noise mixed in, about ``size_bytes`` long."""
    rng = random.Random(seed)
    block = stream_of(telemetry_messages(200, seed), checksum=False)
    pieces: list[bytes] = []
    total = 0
    while total < size_bytes:
        piece = rng.choice([
            block,
            encode(Command("th", (rng.randint(0, 360), rng.randint(0, 100)))),
            b"pid out=+12 depth=101 target=100\r\n",
            bytes(rng.randint(0, 255) for _ in range(8)),
        ])
        pieces.append(piece)
        total += len(piece)
    return b"".join(pieces)


def timed(command: list[str]) -> tuple[float, str]:
    started = time.perf_counter()
    output = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    return time.perf_counter() - started, output


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--megabytes", type=float, default=10.0)
    args = parser.parse_args()
    size_bytes = int(args.megabytes * 1e6)
    with tempfile.TemporaryDirectory() as folder:
        capture = Path(folder) / "capture.bin"
        capture.write_bytes(make_capture(size_bytes, seed=1))
        rng = random.Random(2)
        lines: list[str] = []
        total = 0
        while total < size_bytes:
            lines.append(nmea_sentence(rng.choice(NMEA_BODIES)))
            total += len(lines[-1]) + 1
        nmea_log = Path(folder) / "log.nmea"
        nmea_log.write_text("\n".join(lines) + "\n", encoding="ascii")

        script = Path(folder) / "nmea_peer.py"
        script.write_text(NMEA_SCRIPT, encoding="utf-8")
        rovlink_s, summary = timed([sys.executable, "-m", "rovlink", "decode", "--stats",
                                    str(capture)])
        nmea_s, count = timed([sys.executable, str(script), str(nmea_log)])
    print(f"rovlink decode --stats  {size_bytes / 1e6:.1f} MB in {rovlink_s:.2f} s "
          f"({size_bytes / rovlink_s / 1e6:.2f} MB/s)  {summary.strip()[:120]}...")
    print(f"pynmea2 line by line    {size_bytes / 1e6:.1f} MB in {nmea_s:.2f} s "
          f"({size_bytes / nmea_s / 1e6:.2f} MB/s)  {count.strip()} sentences")
    print(f"ratio                   rovlink is {nmea_s / rovlink_s:.2f}x as fast")


if __name__ == "__main__":
    main()
