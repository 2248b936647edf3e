"""Checksum algorithms (P2)."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rovlink.protocol import ALGORITHMS, Decoder, Frame, UnknownAlgorithmError, get_algorithm
from rovlink.protocol.checksum import crc8_smbus, sum8, xor8


def _crc8_bitwise(data: bytes) -> int:
    """A straightforward bit-by-bit CRC-8 (poly 0x07) to check the table-driven one against."""
    crc = 0
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x07) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc


def test_crc8_smbus_check_value() -> None:
    assert crc8_smbus(b"123456789") == 0xF4


@given(st.binary(max_size=80))
def test_crc8_table_matches_bitwise_definition(data: bytes) -> None:
    assert crc8_smbus(data) == _crc8_bitwise(data)


@pytest.mark.parametrize(
    ("body", "digits"),
    [
        (b"qd", b"8C"),
        (b"mvd.100", b"4B"),
        (b"th.270.25", b"CA"),
        (b"stop", b"A5"),
        (b"qd.123", b"13"),
        (b"qro.-1", b"98"),
    ],
)
def test_part3_vectors(body: bytes, digits: bytes) -> None:
    crc8 = get_algorithm("crc8")
    assert crc8.digits(body) == digits
    assert crc8.verify(body, digits)
    assert crc8.verify(body, digits.lower())


def test_xor_and_sum8() -> None:
    assert xor8(b"qd") == ord("q") ^ ord("d")
    assert sum8(b"qd") == (ord("q") + ord("d")) % 256
    assert get_algorithm("xor").digits(b"qd") == b"%02X" % (ord("q") ^ ord("d"))


@pytest.mark.parametrize("digits", [b"8", b"8C8", b"+C", b" C", b"_8", b"GG", b""])
def test_verify_rejects_anything_but_two_hex_digits(digits: bytes) -> None:
    assert not get_algorithm("crc8").verify(b"qd", digits)


def test_unknown_algorithm_names_the_choices() -> None:
    with pytest.raises(UnknownAlgorithmError, match=r"'md5'.*crc8, sum8, xor"):
        get_algorithm("md5")
    assert set(ALGORITHMS) == {"crc8", "xor", "sum8"}


@pytest.mark.parametrize(
    ("start", "body", "xor_digits", "sum8_digits"),
    [
        # Odd lengths and sums past 255, where a slip in either algorithm shows.
        (b"#", b"th.270.25", b"2E", b"38"),
        (b"#", b"mvd.100", b"60", b"06"),
        (b"$", b"qro.-1", b"5E", b"DE"),
    ],
)
def test_xor_and_sum8_vectors(
    start: bytes, body: bytes, xor_digits: bytes, sum8_digits: bytes
) -> None:
    assert get_algorithm("xor").digits(body) == xor_digits
    assert get_algorithm("sum8").digits(body) == sum8_digits
    for algorithm, digits in (("xor", xor_digits), ("sum8", sum8_digits)):
        decoder = Decoder(checksum_enabled=True, algorithm=algorithm)
        (event,) = decoder.feed(start + body + digits.lower() + b"!")
        assert isinstance(event, Frame), (algorithm, event)
