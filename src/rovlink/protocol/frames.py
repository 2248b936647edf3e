"""Frame encoding and body parsing (PROTOCOL.md P1, P2, P3, P6, P15).

``encode`` turns a message into bytes for the wire; ``parse_body`` turns the body of a received
frame, already stripped of start, end and checksum, into a message or a :class:`FrameError` that
says why it is not one.
"""

from __future__ import annotations

from rovlink.protocol.checksum import (
    CRC8_SMBUS_SHIFTS,
    ChecksumAlgorithm,
    crc8_smbus,
    get_algorithm,
)
from rovlink.protocol.commands import COMMANDS, SPELLINGS, Argument, Kind, Setting, Spec
from rovlink.protocol.messages import Command, Message, Response, trusted_message
from rovlink.protocol.text_enum import StrEnum

__all__ = [
    "BITS_PER_BYTE_8N1",
    "CHECKSUM_MODE_FRAMES",
    "MAX_FRAME_BYTES",
    "FrameError",
    "Reason",
    "checksum_mode_frame",
    "decode_body",
    "encode",
    "parse_body",
]

#: Bits a byte takes on the serial line, 8N1 (P19): a start bit, eight data bits, a stop bit.
BITS_PER_BYTE_8N1 = 10

#: The longest whole frame, start and end characters included (P1).
MAX_FRAME_BYTES = 64

#: The frames that switch the checksum mode, recognised by exact match in either mode (P3), and
#: the mode each sets: ``{b"#crcon!": True, b"#crcoff!": False}``, from the command table.
CHECKSUM_MODE_FRAMES: dict[bytes, bool] = {
    b"#" + spec.name.encode() + b"!": bool(spec.setting_value)
    for spec in COMMANDS
    if spec.setting is Setting.CHECKSUM
}


def checksum_mode_frame(data: bytes) -> bool | None:
    """The checksum mode ``data`` sets if it is exactly a mode frame, else ``None``.

    >>> checksum_mode_frame(b"#crcoff!"), checksum_mode_frame(b"#crcoff9A!")
    (False, None)
    """
    return CHECKSUM_MODE_FRAMES.get(bytes(data))


class Reason(StrEnum):
    """Why a received frame was dropped: machine-readable, stable names."""

    CHECKSUM = "checksum"
    TOO_LONG = "too_long"
    UNKNOWN = "unknown"
    RANGE = "range"
    MALFORMED = "malformed"
    TRUNCATED = "truncated"


class FrameError(Exception):
    """A received frame that is not a valid message (the peer's mistake, not the caller's)."""

    def __init__(self, reason: Reason, detail: str) -> None:
        super().__init__(detail)
        self.reason = reason
        self.detail = detail


_MESSAGE_CLASS: dict[Kind, type[Message]] = {Kind.COMMAND: Command, Kind.RESPONSE: Response}


def encode(message: Message, checksum: str | ChecksumAlgorithm | None = None) -> bytes:
    """The frame for ``message``; with ``checksum`` (an algorithm or its name), checksummed.

    ``crcon`` and ``crcoff`` never carry a checksum (P3).

    >>> encode(Command("th", (270, 25)))
    b'#th.270.25!'
    >>> encode(Command("qd"), checksum="crc8")
    b'#qd8C!'
    """
    body = message.body.encode("ascii")
    start = message.kind.start_byte
    if checksum is None or message.spec.exact_match:
        return start + body + b"!"
    return start + body + get_algorithm(checksum).digits(body) + b"!"


def _find_spec(kind: Kind, body: str) -> tuple[Spec, str | None]:
    """The spec whose spelling the body starts with, and the argument text after its ``.``."""
    spellings = SPELLINGS[kind]
    spec = spellings.get(body)
    if spec is not None:
        return spec, None
    # A name may itself contain "." (q.l): try the longest spelling first.
    position = body.rfind(".")
    while position > 0:
        spec = spellings.get(body[:position])
        if spec is not None:
            return spec, body[position + 1 :]
        position = body.rfind(".", 0, position)
    raise FrameError(Reason.UNKNOWN, f"unknown {kind.value} {body.split('.', 1)[0]!r}")


def _parse_number(text: str, signed: bool) -> int:
    digits = text[1:] if signed and text[:1] in ("+", "-") else text
    if not digits or not digits.isascii() or not digits.isdigit():
        raise ValueError(text)
    value = int(digits)
    return -value if text[0] == "-" else value


def _split_values(kind: Kind, spec: Spec, text: str | None) -> list[str]:
    tokens = [] if text is None else text.split(".")
    if (
        kind is Kind.RESPONSE
        and len(spec.arguments) == 1
        and spec.arguments[0].signed
        and len(tokens) == 2
        and tokens[0] in ("+", "-")
    ):
        # The original template writes roll as "$qro.-.1!" (P15): accept the sign on its own.
        tokens = [tokens[0] + tokens[1]]
    return tokens


def parse_body(kind: Kind, body: str) -> Message:
    """The message in a frame body (checksum already stripped), or raise :class:`FrameError`.

    >>> parse_body(Kind.RESPONSE, "qro.-.7")
    Response(name='qro', values=(-7,))
    """
    spec, text = _find_spec(kind, body)
    tokens = _split_values(kind, spec, text)
    if len(tokens) != len(spec.arguments):
        raise FrameError(
            Reason.MALFORMED,
            f"{spec.name} takes {len(spec.arguments)} value(s), got {len(tokens)}",
        )
    values = []
    for token, argument in zip(tokens, spec.arguments, strict=True):
        try:
            value = _parse_number(token, argument.signed)
        except ValueError:
            raise FrameError(
                Reason.MALFORMED, f"{spec.name}: {argument.name} is not a number: {token!r}"
            ) from None
        if not argument.minimum <= value <= argument.maximum:
            raise FrameError(
                Reason.RANGE,
                f"{spec.name}: {argument.name} must be in {argument.range_text()}, got {value}",
            )
        values.append(value)
    return _MESSAGE_CLASS[kind](spec.name, tuple(values))


# What the fast path needs to parse the values of one spelling: its spec, the message class, the
# rest of its name after the first "." (with its own "."), the value count, and per value whether
# it is signed and its range.
_Valued = tuple[Spec, type[Message], bytes, int, bool, int, int, bool, int, int]


def _fast_tables(kind: Kind) -> tuple[dict[bytes, Spec], dict[bytes, _Valued]]:
    """The spellings without values by body, and those with one or two values by the first
    segment of their name (where that segment names one such spelling only)."""
    bare: dict[bytes, Spec] = {}
    valued: dict[bytes, list[_Valued]] = {}
    cls = _MESSAGE_CLASS[kind]
    for spelling, spec in SPELLINGS[kind].items():
        arguments = spec.arguments
        if not arguments:
            bare[spelling.encode()] = spec
        elif len(arguments) <= 2:
            head, _, name_rest = spelling.partition(".")
            first, second = arguments[0], arguments[-1]
            valued.setdefault(head.encode(), []).append(
                (
                    spec,
                    cls,
                    (name_rest + "." if name_rest else "").encode(),
                    len(arguments),
                    first.signed,
                    first.minimum,
                    first.maximum,
                    second.signed,
                    second.minimum,
                    second.maximum,
                )
            )
    return bare, {head: entries[0] for head, entries in valued.items() if len(entries) == 1}


_FAST = {kind: _fast_tables(kind) for kind in Kind}


def decode_body(kind: Kind, body: bytes) -> Message:
    """As :func:`parse_body`, for the raw bytes of a body: the decoder's fast path.

    Well-formed bodies in the canonical forms are taken by table lookups and ``bytes.isdigit``;
    anything else goes to :func:`parse_body`, which names the exact problem.

    >>> decode_body(Kind.COMMAND, b"th.270.25")
    Command(name='th', values=(270, 25))
    """
    bare, valued = _FAST[kind]
    head, dot, rest = body.partition(b".")
    entry = valued.get(head) if dot else None
    if entry is not None:
        spec, cls, name_rest, count, signed, minimum, maximum, signed_2, minimum_2, maximum_2 = (
            entry
        )
        if name_rest:  # a name with a "." in it, such as "q.l"
            if not rest.startswith(name_rest):
                return parse_body(kind, body.decode("ascii", errors="replace"))
            rest = rest[len(name_rest) :]
        # Spelled out for one and two values (every command of the table): the hot path. A value
        # is ASCII digits (bytes.isdigit is ASCII only), after a sign if the argument is signed.
        if count == 1:
            if rest.isdigit() or (signed and rest[1:].isdigit() and rest[0] in b"+-"):
                value = int(rest)
                if minimum <= value <= maximum:
                    return trusted_message(cls, spec, (value,))
        else:
            first_text, _, second_text = rest.partition(b".")
            if (
                first_text.isdigit()
                or (signed and first_text[1:].isdigit() and first_text[0] in b"+-")
            ) and (
                second_text.isdigit()
                or (signed_2 and second_text[1:].isdigit() and second_text[0] in b"+-")
            ):
                first, second = int(first_text), int(second_text)
                if minimum <= first <= maximum and minimum_2 <= second <= maximum_2:
                    return trusted_message(cls, spec, (first, second))
    else:
        bare_spec = bare.get(body)
        if bare_spec is not None:  # a bare name such as "qd", "stop" or "q.l"
            return trusted_message(_MESSAGE_CLASS[kind], bare_spec, ())
    return parse_body(kind, body.decode("ascii", errors="replace"))


# -- the decoder's table for frames with values ---------------------------------------------------

#: A number as it appears in a frame: its value; for CRC-8/SMBUS, the zero-shift table of its
#: length and the CRC of its text (see :data:`CRC8_SMBUS_SHIFTS`); and for the value of a command
#: that takes one, the message it makes (messages are immutable, so one serves every such frame).
NumberText = tuple[int, bytes, int, "Message | None"]


class NumberTexts(dict[bytes, "NumberText | None"]):
    """The spellings of one argument's values met so far, text to :data:`NumberText`.

    ``numbers[text]`` is ``None`` for a text that is not an in-range value of the argument (the
    full parser then names the problem). With a ``spec`` of one argument, each number holds the
    message of that value. Only canonical spellings are kept (no leading zeros), so the table
    never holds more than three entries per value of the argument's range (``5``, ``+5``, ``-5``
    for a signed one), however long the stream: its size is bounded by the command table.
    """

    __slots__ = ("cls", "maximum", "minimum", "signed", "spec")

    def __init__(
        self, argument: Argument, spec: Spec | None = None, cls: type[Message] | None = None
    ) -> None:
        super().__init__()
        self.signed = argument.signed
        self.minimum = argument.minimum
        self.maximum = argument.maximum
        self.spec = spec
        self.cls = cls

    def __missing__(self, text: bytes) -> NumberText | None:
        digits = text[1:] if self.signed and text[:1] in (b"+", b"-") else text
        if not digits.isdigit() or len(text) >= len(CRC8_SMBUS_SHIFTS):  # ASCII digits only
            return None
        value = -int(digits) if text[:1] == b"-" else int(digits)
        if not self.minimum <= value <= self.maximum:
            return None
        message = None
        if self.spec is not None and self.cls is not None:
            message = trusted_message(self.cls, self.spec, (value,))
        number = (value, CRC8_SMBUS_SHIFTS[len(text)], crc8_smbus(text), message)
        if digits[:1] != b"0" or len(digits) == 1:  # canonical: remembered
            self[text] = number
        return number


class EndedNumberTexts(dict[bytes, "NumberText | None"]):
    """As :class:`NumberTexts`, for texts followed by the frame's end ``!``: the last value of a
    frame without a checksum, taken without a slice to cut the end off. Shares its numbers (and
    their messages) with the plain table."""

    __slots__ = ("numbers",)

    def __init__(self, numbers: NumberTexts) -> None:
        super().__init__()
        self.numbers = numbers

    def __missing__(self, text: bytes) -> NumberText | None:
        if text[-1:] != b"!":
            return None
        bare = text[:-1]
        number = self.numbers[bare]
        if number is not None and bare in self.numbers:  # canonical: remembered
            self[text] = number
        return number


#: What the decoder's fast path needs to take a frame with values, found by the part before the
#: frame's first "." (``b"#th"``): the spec; the message class; how many parts ``raw.split(b".")``
#: gives; the rest of the name (``b"l"`` of ``q.l``) or ``b""``; the numbers of the first
#: argument; those of the last argument, without and with the end ``!`` after them; and the
#: CRC-8/SMBUS of the name and its "." (the prefix of every such body).
FastEntry = tuple[Spec, type[Message], int, bytes, NumberTexts, NumberTexts, EndedNumberTexts, int]


def _fast_table() -> dict[bytes, FastEntry]:
    entries: dict[bytes, list[FastEntry]] = {}
    for kind in Kind:
        cls = _MESSAGE_CLASS[kind]
        for spelling, spec in SPELLINGS[kind].items():
            arguments = spec.arguments
            if not 1 <= len(arguments) <= 2:
                continue
            head, _, name_rest = spelling.partition(".")
            if "." in name_rest:
                continue  # no such name today; the full parser takes it
            first, last = arguments[0], arguments[-1]
            last_numbers = (
                NumberTexts(last, spec, cls) if len(arguments) == 1 else NumberTexts(last)
            )
            entries.setdefault(kind.start_byte + head.encode(), []).append(
                (
                    spec,
                    cls,
                    1 + bool(name_rest) + len(arguments),
                    name_rest.encode(),
                    NumberTexts(first),
                    last_numbers,
                    EndedNumberTexts(last_numbers),
                    crc8_smbus((spelling + ".").encode()),
                )
            )
    # A first segment shared by two spellings is left to the full parser.
    return {head: found[0] for head, found in entries.items() if len(found) == 1}


#: The frames with one or two values, by the part of the frame before its first ".".
FAST_ENTRIES = _fast_table()
