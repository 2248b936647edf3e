"""The test vectors of PROTOCOL.md, read from PROTOCOL.md itself (P2, Part 3): a vector changed
or added there is checked here without a second copy to keep in step."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rovlink.protocol import (
    BadFrame,
    Command,
    Decoder,
    Frame,
    Kind,
    Reason,
    encode,
    get_algorithm,
    parse_body,
)
from rovlink.protocol.checksum import crc8_smbus

PROTOCOL = Path(__file__).resolve().parents[2] / "PROTOCOL.md"
_TEXT = PROTOCOL.read_text(encoding="utf-8")
_PART_3 = _TEXT.split("## Part 3", 1)[1]
#: ``| `qd` | 8C | `#qd8C!` |``
_VECTOR = re.compile(r"^\| `([^`]+)` \| ([0-9A-Fa-f]{2}) \| `([#$][^`]+!)` \|$", re.MULTILINE)
_VECTORS = _VECTOR.findall(_PART_3)


def test_part_3_is_read() -> None:
    assert len(_VECTORS) == len([line for line in _PART_3.splitlines() if line.startswith("| `")])
    assert len(_VECTORS) >= 6


def test_the_check_value_of_p2() -> None:
    (text, value) = re.findall(r"check value of `([^`]+)` is 0x([0-9A-F]{2})", _TEXT)[0]
    assert crc8_smbus(text.encode()) == int(value, 16)


@pytest.mark.parametrize(("body", "crc", "frame"), _VECTORS)
def test_each_vector_encodes_and_decodes(body: str, crc: str, frame: str) -> None:
    kind = Kind.COMMAND if frame.startswith("#") else Kind.RESPONSE
    assert frame == kind.start_byte.decode() + body + crc + "!"
    assert get_algorithm("crc8").digits(body.encode()) == crc.encode()
    message = parse_body(kind, body)
    assert encode(message, checksum="crc8") == frame.encode()
    for raw in (frame.encode(), frame.encode()[:-3] + crc.lower().encode() + b"!"):
        assert Decoder(checksum_enabled=True).feed(raw) == [Frame(message, raw)]
    # With the mode off, the frame is taken as it is: the digits are not a checksum.
    (event,) = Decoder().feed(frame.encode())
    assert not (isinstance(event, Frame) and event.message == message)


def test_the_closing_sentence_of_part_3() -> None:
    # "#crcon! and #crcoff! never carry a checksum; in checksum mode #stop! is honoured and
    # #qd! is dropped; with checksum off #qd8C! is an unknown command and is dropped."
    for name in ("crcon", "crcoff"):
        assert encode(Command(name), checksum="crc8") == b"#" + name.encode() + b"!"
    checked = Decoder(checksum_enabled=True)
    assert checked.feed(b"#stop!") == [Frame(Command("stop"), b"#stop!")]
    (dropped,) = checked.feed(b"#qd!")
    assert isinstance(dropped, BadFrame)
    assert dropped.reason is Reason.CHECKSUM
    (unknown,) = Decoder().feed(b"#qd8C!")
    assert isinstance(unknown, BadFrame)
    assert unknown.reason is Reason.UNKNOWN
