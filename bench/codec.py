"""Decoder throughput: rovlink's streaming decoder against pynmea2 on sentences of similar length.

    python bench/codec.py [--frames N] [--repeat R]

Prints frames/s and MB/s of ``Decoder.feed`` (fed in 4 KiB chunks, as from a serial port), with
and without checksums, on two streams: "random", commands and responses of the whole table with
values drawn across their ranges (nearly every frame is new: the decoder's worst case), and
"telemetry", a host polling ``#qsa!`` and the six replies of a robot whose sensors drift as a real
one's do. ``pynmea2.parse`` on NMEA sentences of similar length is measured in the same run,
interleaved with the decoder runs so that both see the same machine load, and the ratio printed.
"""

from __future__ import annotations

import argparse
import random
import time
from collections import deque
from collections.abc import Callable

import pynmea2

from rovlink.protocol import (
    COMMANDS,
    RESPONSES,
    Command,
    Decoder,
    Frame,
    Kind,
    Message,
    Response,
    lookup,
)
from rovlink.protocol import encode as encode_message

CHUNK_BYTES = 4096

NMEA_BODIES = [
    "HCHDG,101.1,,,7.1,W",
    "GPHDT,274.07,T",
    "YXXDR,C,19.3,C,WTHI",
    "SDDPT,2.4,0.1",
    "IIMTW,17.9,C",
    "GPROT,35.6,A",
]


def nmea_sentence(body: str) -> str:
    """A sentence with its XOR checksum, as an instrument sends it."""
    checksum = 0
    for byte in body.encode("ascii"):
        checksum ^= byte
    return f"${body}*{checksum:02X}"


def mixed_messages(count: int, seed: int) -> list[Message]:
    """Random commands and responses over the whole table, values drawn across their ranges."""
    rng = random.Random(seed)
    # crcon and crcoff would switch the mode of the stream itself.
    specs = [spec for spec in (*COMMANDS, *RESPONSES) if not spec.exact_match]
    messages: list[Message] = []
    for _ in range(count):
        spec = rng.choice(specs)
        values = tuple(rng.randint(a.minimum, a.maximum) for a in spec.arguments)
        cls = Command if spec.kind is Kind.COMMAND else Response
        messages.append(cls(spec.name, values))
    return messages


#: The frames of the "all-new" stream: commands and replies that carry values.
ALL_NEW_SPECS = (
    *(("command", name) for name in ("th", "mvd", "mvs", "sdz")),
    *(("response", name) for name in ("qd", "qr", "qro", "qpi", "qhe")),
)
#: No frame of the "all-new" stream repeats within this many frames: twice the decoder's cache of
#: 512 frames, so that no frame is ever found in it.
ALL_NEW_WINDOW = 1024


def all_new_messages(count: int, seed: int) -> list[Message]:
    """Commands and replies with values (``th``, ``mvd``, ``mvs``, ``sdz``; ``qd``, ``qr``,
    ``qro``, ``qpi``, ``qhe``), values drawn at random, no frame repeated within
    :data:`ALL_NEW_WINDOW` frames."""
    rng = random.Random(seed)
    specs = [lookup(name, Kind(kind)) for kind, name in ALL_NEW_SPECS]
    recent: deque[tuple[str, tuple[int, ...]]] = deque()
    seen: set[tuple[str, tuple[int, ...]]] = set()
    messages: list[Message] = []
    while len(messages) < count:
        spec = rng.choice(specs)
        values = tuple(rng.randint(a.minimum, a.maximum) for a in spec.arguments)
        key = (spec.kind.value + spec.name, values)
        if key in seen:
            continue
        seen.add(key)
        recent.append(key)
        if len(recent) > ALL_NEW_WINDOW:
            seen.discard(recent.popleft())
        cls = Command if spec.kind is Kind.COMMAND else Response
        messages.append(cls(spec.name, values))
    return messages


def stream_of(messages: list[Message], checksum: bool) -> bytes:
    """The frames back to back, as the controller's replies arrive after a burst of queries."""
    algorithm = "crc8" if checksum else None
    return b"".join(encode_message(message, checksum=algorithm) for message in messages)


def telemetry_messages(polls: int, seed: int) -> list[Message]:
    """``#qsa!`` and its six replies, ``polls`` times, the readings drifting slowly."""
    rng = random.Random(seed)
    depth_cm, roll_deg, pitch_deg, heading_deg = 100.0, 0.0, 0.0, 90.0
    messages: list[Message] = []
    for _ in range(polls):
        depth_cm = min(max(depth_cm + rng.gauss(0, 0.5), 0), 9999)
        roll_deg = min(max(roll_deg + rng.gauss(0, 0.3), -90), 90)
        pitch_deg = min(max(pitch_deg + rng.gauss(0, 0.3), -90), 90)
        heading_deg = (heading_deg + rng.gauss(0, 0.5)) % 360
        messages += [
            Command("qsa"),
            Response("qd", (round(depth_cm),)),
            Response("qr", (min(1024, 102 + round(depth_cm * 0.46)),)),
            Response("q.l", (0,)),
            Response("qro", (round(roll_deg),)),
            Response("qpi", (round(pitch_deg),)),
            Response("qhe", (round(heading_deg) % 360,)),
        ]
    return messages


def interleaved_best(
    repeat: int, runs: dict[str, Callable[[], int]]
) -> dict[str, tuple[float, int]]:
    """The fastest of ``repeat`` rounds per run (seconds, and what the run counted).

    Rounds alternate between the runs, so that a change of machine load touches all alike.
    """
    best: dict[str, tuple[float, int]] = {}
    for _ in range(repeat):
        for label, run in runs.items():
            started = time.perf_counter()
            counted = run()
            seconds = time.perf_counter() - started
            if label not in best or seconds < best[label][0]:
                best[label] = (seconds, counted)
    return best


def decode_run(stream: bytes, checksum: bool, expected: int) -> Callable[[], int]:
    def run() -> int:
        decoder = Decoder(checksum_enabled=checksum)
        frames = 0
        for start in range(0, len(stream), CHUNK_BYTES):
            for event in decoder.feed(stream[start : start + CHUNK_BYTES]):
                if isinstance(event, Frame):
                    frames += 1
        # Every frame of the stream must have come out: a fast wrong decoder is no result.
        if frames != expected:
            raise AssertionError(f"decoded {frames} frames, expected {expected}")
        return frames

    return run


def nmea_run(sentences: list[str]) -> Callable[[], int]:
    def run() -> int:
        parsed = 0
        for sentence in sentences:
            pynmea2.parse(sentence, check=True)
            parsed += 1
        return parsed

    return run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()

    rng = random.Random(2)
    sentences = [nmea_sentence(rng.choice(NMEA_BODIES)) for _ in range(args.frames)]
    nmea_bytes = sum(len(s) + 2 for s in sentences)
    streams = {
        "all-new": all_new_messages(args.frames, seed=4),
        "random": mixed_messages(args.frames, seed=1),
        "telemetry": telemetry_messages(args.frames // 7, seed=3),
    }
    runs: dict[str, Callable[[], int]] = {"pynmea2": nmea_run(sentences)}
    sizes: dict[str, int] = {"pynmea2": nmea_bytes}
    for stream_name, messages in streams.items():
        for checksum in (False, True):
            label = f"{stream_name} {'crc8' if checksum else 'plain'}"
            stream = stream_of(messages, checksum)
            runs[label] = decode_run(stream, checksum, expected=len(messages))
            sizes[label] = len(stream)
    best = interleaved_best(args.repeat, runs)

    nmea_s, nmea_count = best["pynmea2"]
    nmea_rate = nmea_count / nmea_s
    print(
        f"{'pynmea2.parse':24} {nmea_rate:>10,.0f} sentences/s "
        f"{nmea_bytes / nmea_s / 1e6:6.2f} MB/s  (mean {nmea_bytes / nmea_count:.1f} B)"
    )
    for label, (seconds, count) in best.items():
        if label == "pynmea2":
            continue
        rate = count / seconds
        print(
            f"{'rovlink ' + label:24} {rate:>10,.0f} frames/s    "
            f"{sizes[label] / seconds / 1e6:6.2f} MB/s  (mean {sizes[label] / count:.1f} B)  "
            f"{rate / nmea_rate:5.2f}x pynmea2"
        )


if __name__ == "__main__":
    main()
