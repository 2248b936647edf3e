"""Every argument's range as PROTOCOL.md writes it, for tests of both ends.

Written out here from the protocol's text, not read from the command table: a table that
drifts from the specification (``mgmp`` capped at 254, ``th`` refusing 360) fails the tests that
use these, where tests that walk the table itself would follow it.
"""

from __future__ import annotations

#: (name, (minimum, maximum, signed) per argument), from Part 1 and P6, P9, P10, P18.
COMMAND_RANGES: dict[str, tuple[tuple[int, int, bool], ...]] = {
    "mgmp": ((0, 255, False),),
    "mvpdp": ((0, 99, False),),
    "mvpdi": ((0, 99, False),),
    "mvpidd": ((0, 99, False),),
    "mvpdd": ((0, 99, False),),  # the alias (P18)
    "mvdirect": ((0, 1, False),),
    "mvs": ((-100, 100, True),),
    "mvd": ((0, 9999, False),),
    "th": ((0, 360, False), (0, 100, False)),
    "sdz": ((0, 1024, False),),
    "sdk": ((0, 10000, False),),
}

#: The same for the replies (P13, P14, P15: a heading of 360 is accepted, 0-359 written).
RESPONSE_RANGES: dict[str, tuple[int, int, bool]] = {
    "qd": (0, 9999, False),
    "qr": (0, 1024, False),
    "q.l": (0, 1, False),
    "qro": (-90, 90, True),
    "qpi": (-90, 90, True),
    "qhe": (0, 360, False),
}


def value_text(value: int, signed: bool) -> str:
    """A value as a frame writes it: with a sign if signed (P6)."""
    return f"{value:+d}" if signed else str(value)


def command_body(name: str, values: tuple[int, ...]) -> str:
    """The body of a command frame of ``name`` with ``values``."""
    signs = [signed for _, _, signed in COMMAND_RANGES[name]]
    texts = (value_text(value, signed) for value, signed in zip(values, signs, strict=True))
    return ".".join([name, *texts])


def edge_cases() -> list[tuple[str, tuple[int, ...], bool]]:
    """(name, values, accepted): each argument at its edges and one past them, the others at
    their minimum."""
    cases = []
    for name, arguments in COMMAND_RANGES.items():
        for index, (minimum, maximum, _) in enumerate(arguments):
            for value, accepted in (
                (minimum, True),
                (maximum, True),
                (minimum - 1, False),
                (maximum + 1, False),
            ):
                values = [low for low, _, _ in arguments]
                values[index] = value
                cases.append((name, tuple(values), accepted))
    return cases
