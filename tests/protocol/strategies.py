"""Hypothesis strategies for messages and byte streams, derived from the command table."""

from __future__ import annotations

from hypothesis import strategies as st

from rovlink.protocol import COMMANDS, RESPONSES, Command, Kind, Message, Response, Spec


def _message_for(spec: Spec) -> st.SearchStrategy[Message]:
    cls = Command if spec.kind is Kind.COMMAND else Response
    values = st.tuples(*(st.integers(a.minimum, a.maximum) for a in spec.arguments))
    return values.map(lambda vals: cls(spec.name, vals))


messages: st.SearchStrategy[Message] = st.one_of([_message_for(s) for s in (*COMMANDS, *RESPONSES)])

_NOISE_TOKENS = [
    b"#",
    b"$",
    b"!",
    b".",
    b"q",
    b"d",
    b"1",
    b"\r\n",
    b" ",
    b"\x00",
    b"\xff",
    b"#qd!",
    b"$qd.5!",
    b"#stop!",
    b"#qd8C!",
]
_MODE_FRAMES = [b"#crcon!", b"#crcoff!"]

#: Bytes that look like protocol traffic: frame characters, digits, letters, noise, mode frames.
noisy_bytes = st.binary(max_size=300) | st.lists(
    st.sampled_from(_NOISE_TOKENS + _MODE_FRAMES), max_size=60
).map(b"".join)

#: Line noise that never switches the checksum mode.
line_noise = st.binary(max_size=100).filter(lambda data: b"crcon" not in data) | st.lists(
    st.sampled_from(_NOISE_TOKENS), max_size=30
).map(b"".join)


def split_points(data: bytes) -> st.SearchStrategy[list[int]]:
    """Sorted cut positions that split ``data`` into chunks."""
    return st.lists(st.integers(0, len(data)), max_size=12).map(sorted)
