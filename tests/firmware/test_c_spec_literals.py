"""The C reference against PROTOCOL.md's own words, not against the Python controller: the
ranges at their edges, the signed zero, Part 3's vectors, a byte outside 0x21-0x7E in a frame.

(The differential tests show the C layer and the Python controller agree; these show the
agreement is on what the protocol says.)
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from rovlink.protocol import COMMANDS, lookup
from rovlink.protocol.checksum import crc8_smbus
from tests.firmware.c_build import FIRMWARE, LAYER, STRICT, build, needs_gcc
from tests.protocol.spec_ranges import command_body, edge_cases
from tests.protocol.test_frames import SEED_FRAMES

pytestmark = [pytest.mark.integration, needs_gcc]


@pytest.fixture(scope="module")
def replay(tmp_path_factory: pytest.TempPathFactory) -> Path:
    binary = tmp_path_factory.mktemp("c") / "replay"
    return build(binary, [FIRMWARE / "host" / "replay.c", *LAYER], *STRICT, "-O1")


def _run(replay: Path, stream: bytes, *sensors: int) -> list[str]:
    """The lines of ``replay``: C (dispatched), R (reply) and D (debug) lines."""
    arguments = [str(replay), "4096", "0", "debug", *(str(value) for value in sensors)]
    result = subprocess.run(arguments, input=stream, capture_output=True, check=True, timeout=30)
    return result.stdout.decode("ascii").splitlines()


@pytest.mark.parametrize(("name", "values", "accepted"), edge_cases())
def test_the_c_layer_takes_each_edge_and_drops_one_past_it(
    replay: Path, name: str, values: tuple[int, ...], accepted: bool
) -> None:
    setup = b"#debug1!#start!" + (b"#mvdirect.1!" if name == "mvs" else b"")
    body = command_body(name, values)
    lines = _run(replay, setup + f"#{body}!".encode())[len(_run(replay, setup)) :]
    index = COMMANDS.index(lookup(name))
    dispatched = [line for line in lines if line.startswith("C ")]
    if accepted:
        if name == "mvdirect" and values == (0,):
            assert dispatched == [], lines  # already in depth mode: nothing changed (P9)
        else:
            assert dispatched == [" ".join(["C", str(index), *map(str, values)])], lines
    else:
        assert dispatched == [], lines
        assert any(line.startswith("D dropped <" + body) for line in lines), lines


def test_signed_zero_is_written_plus_zero_and_qsa_is_six_replies_in_order(replay: Path) -> None:
    # P6, P15: "$qro.+0!"; P12: qd, qr, q.l, qro, qpi, qhe, back to back.
    lines = _run(replay, b"#qro!#qpi!#qsa!", 0, 0, 0, 0, 0, 0)
    replies = "".join(line[2:] for line in lines if line.startswith("R "))
    assert replies == "$qro.+0!$qpi.+0!$qd.0!$qr.0!$q.l.0!$qro.+0!$qpi.+0!$qhe.0!"


def test_part_3_vectors(replay: Path) -> None:
    # In checksum mode: "#qd8C!" answered with "$qd.12313!", "#qro..!" with "$qro.-198!", the
    # bare "#qd!" dropped, the bare "#stop!" honoured; with it off, "#qd8C!" is unknown.
    stream = (
        b"#debug1!#crcon!#qd8C!#qro"
        + b"%02X" % crc8_smbus(b"qro")
        + b"!#qd!#start"
        + b"%02X" % crc8_smbus(b"start")
        + b"!#stop!#crcoff!#qd8C!"
    )
    lines = _run(replay, stream, 123, 530, 0, -1, 3, 275)
    replies = [line[2:] for line in lines if line.startswith("R ")]
    assert replies == ["$qd.12313!", "$qro.-198!"]
    dispatched = [line for line in lines if line.startswith("C ")]
    index = COMMANDS.index
    assert dispatched == [f"C {index(lookup('start'))}", f"C {index(lookup('stop'))}"]
    dropped = [line for line in lines if line.startswith("D dropped")]
    assert dropped == [
        "D dropped <qd>: missing or wrong checksum",
        "D dropped <qd8C>: unknown command",
    ]


@pytest.mark.parametrize("byte", [b" ", b"\x7f", b"\x00", b"\xa0"])
def test_a_byte_outside_the_printable_range_discards_the_frame(replay: Path, byte: bytes) -> None:
    # P1: the frame is discarded at that byte, which is then between frames.
    lines = _run(replay, b"#debug1!#mgmp.1" + byte + b"5!#qd!")
    assert lines[1] == "D dropped <mgmp.1>: a byte outside 0x21-0x7E", lines
    assert [line for line in lines if line.startswith(("C ", "R "))] == ["R $qd.1020!"]


@pytest.mark.parametrize("frame", [raw for raw, _, _ in SEED_FRAMES if raw.startswith(b"#")])
def test_the_c_layer_takes_every_command_frame_of_the_original(replay: Path, frame: bytes) -> None:
    name = frame[1:-1].split(b".")[0]
    setup = b"#debug1!#start!" + (b"#mvdirect.1!" if name in (b"mvs", b"mvdirect") else b"")
    lines = _run(replay, setup + frame)[len(_run(replay, setup)) :]
    assert not [line for line in lines if line.startswith("D dropped")], lines
    if name not in (b"crcon", b"crcoff", b"debug1", b"debug0"):
        assert lines, frame  # a reply, a dispatch or a line about what it set (P4, P5)
