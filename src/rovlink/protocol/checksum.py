"""Checksum algorithms for frame bodies (PROTOCOL.md P2).

The original specification leaves the algorithm undefined, so it is pluggable: a real controller
may use another one. Every algorithm maps the BODY bytes (without the start and end characters)
to one byte, sent as two hex digits.
"""

from __future__ import annotations

from rovlink.protocol.frozen import frozen

# Not typing's: the protocol core is on the start-up path of ``rovlink decode``.
TYPE_CHECKING = False

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = [
    "ALGORITHMS",
    "CRC8_SMBUS_SHIFTS",
    "CRC8_SMBUS_TABLE",
    "DEFAULT_ALGORITHM",
    "HEX_DIGITS",
    "HEX_DIGITS_END",
    "ChecksumAlgorithm",
    "UnknownAlgorithmError",
    "crc8_smbus",
    "get_algorithm",
    "sum8",
    "xor8",
]


def _make_crc8_table(polynomial: int) -> tuple[int, ...]:
    table = []
    for byte in range(256):
        crc = byte
        for _ in range(8):
            crc = ((crc << 1) ^ polynomial) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table.append(crc)
    return tuple(table)


#: The CRC-8/SMBUS of every byte value (for callers that run the table loop inline).
CRC8_SMBUS_TABLE = _make_crc8_table(0x07)
#: The two uppercase hex digits of every byte value, as a checksum is sent: a lookup is cheaper
#: than formatting on the decoder's hot path.
HEX_DIGITS: tuple[bytes, ...] = tuple(b"%02X" % value for value in range(256))
#: The checksum digits and the end character, to check a whole frame's tail with one ``endswith``.
HEX_DIGITS_END: tuple[bytes, ...] = tuple(digits + b"!" for digits in HEX_DIGITS)


def _zero_shift_tables(count: int) -> tuple[bytes, ...]:
    table = bytes(CRC8_SMBUS_TABLE)
    shifts = [bytes(range(256))]
    for _ in range(count):
        shifts.append(shifts[-1].translate(table))
    return tuple(shifts)


#: ``CRC8_SMBUS_SHIFTS[n][state]`` is the CRC-8/SMBUS register after ``n`` zero bytes from
#: ``state``. The CRC is linear, so the register after bytes ``b`` from ``state`` is
#: ``CRC8_SMBUS_SHIFTS[len(b)][state] ^ crc8_smbus(b)``: a decoder that knows the CRC of a piece
#: (a name, a number) continues across it with one lookup instead of a loop over its bytes.
CRC8_SMBUS_SHIFTS = _zero_shift_tables(64)


def crc8_smbus(data: bytes) -> int:
    """CRC-8/SMBUS: poly 0x07, init 0, no reflection, xorout 0.

    >>> hex(crc8_smbus(b"123456789"))
    '0xf4'
    """
    crc = 0
    table = CRC8_SMBUS_TABLE
    for byte in data:
        crc = table[crc ^ byte]
    return crc


def xor8(data: bytes) -> int:
    """NMEA-style XOR of all bytes.

    >>> xor8(b"qd") == ord("q") ^ ord("d")
    True
    """
    result = 0
    for byte in data:
        result ^= byte
    return result


def sum8(data: bytes) -> int:
    """Sum of all bytes modulo 256.

    >>> sum8(b"\\xff\\x02")
    1
    """
    return sum(data) & 0xFF


@frozen
class ChecksumAlgorithm:
    """A named checksum function with its two-hex-digit rendering."""

    __slots__ = ("description", "function", "name")
    __match_args__ = ("name", "function", "description")

    name: str
    function: Callable[[bytes], int]
    description: str

    def __init__(self, name: str, function: Callable[[bytes], int], description: str) -> None:
        _set = object.__setattr__
        _set(self, "name", name)
        _set(self, "function", function)
        _set(self, "description", description)

    def digits(self, body: bytes) -> bytes:
        """The two uppercase hex digits that follow ``body`` in a frame.

        >>> get_algorithm("crc8").digits(b"qd")
        b'8C'
        """
        return b"%02X" % self.function(body)

    def verify(self, body: bytes, digits: bytes) -> bool:
        """Whether ``digits`` (either case) is the checksum of ``body``."""
        # Only two hex digits can equal the rendering, so no separate syntax check is needed.
        value = self.function(body)
        if not 0 <= value <= 0xFF:  # not one byte: only a foreign function returns that
            return b"%02X" % value == digits.upper()
        expected = HEX_DIGITS[value]
        return digits == expected or digits.upper() == expected


ALGORITHMS: dict[str, ChecksumAlgorithm] = {
    algorithm.name: algorithm
    for algorithm in (
        ChecksumAlgorithm("crc8", crc8_smbus, "CRC-8/SMBUS (poly 0x07, init 0x00), the default"),
        ChecksumAlgorithm("xor", xor8, "XOR of the body bytes, as in NMEA 0183"),
        ChecksumAlgorithm("sum8", sum8, "sum of the body bytes modulo 256"),
    )
}
DEFAULT_ALGORITHM = "crc8"


class UnknownAlgorithmError(ValueError):
    """A checksum algorithm name that is not in :data:`ALGORITHMS`."""


def get_algorithm(algorithm: str | ChecksumAlgorithm) -> ChecksumAlgorithm:
    """Look an algorithm up by name (``crc8``, ``xor``, ``sum8``); an instance passes through.

    >>> get_algorithm("xor").name
    'xor'
    """
    if isinstance(algorithm, ChecksumAlgorithm):
        return algorithm
    try:
        return ALGORITHMS[algorithm]
    except KeyError:
        known = ", ".join(sorted(ALGORITHMS))
        raise UnknownAlgorithmError(
            f"unknown checksum algorithm {algorithm!r}; expected one of: {known}"
        ) from None
