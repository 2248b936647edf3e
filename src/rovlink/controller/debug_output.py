"""Debug lines (P5): text that no decoder can mistake for a frame."""

from __future__ import annotations

from rovlink.protocol.announcements import DEBUG_PREFIX

__all__ = ["debug_line", "describe_frame"]

# The three frame characters become look-alikes that are plain text, and the typography of
# messages (ranges such as "0–255") becomes ASCII for any terminal.
_SAFE = str.maketrans(
    {
        "#": "No.",
        "$": "S",
        "!": ".",
        "\r": " ",
        "\n": " ",
        "–": "-",
        "—": "-",
        "−": "-",
        "…": "...",
        "·": "*",
        "×": "x",
        "≥": ">=",
        "≤": "<=",
        "°": " deg",
    }
)
_DEBUG_PREFIX_BYTES = DEBUG_PREFIX.encode("ascii")
_PRINTABLE = frozenset(range(0x20, 0x7F))


def debug_line(text: str) -> bytes:
    """One debug line, CR LF ended, with ``#``, ``$``, ``!`` and line breaks replaced.

    >>> debug_line("dropped #qd!: must be in 0–255")
    b'debug: dropped No.qd.: must be in 0-255\\r\\n'
    """
    safe = text.translate(_SAFE)
    return _DEBUG_PREFIX_BYTES + safe.encode("ascii", errors="backslashreplace") + b"\r\n"


def describe_frame(raw: bytes) -> str:
    """A received frame for a debug line: ``<body>`` without start and end, bytes escaped.

    >>> describe_frame(b"#mvd.12x\\x01!")
    '<mvd.12x\\\\x01>'
    """
    body = raw[1:] if raw[:1] in (b"#", b"$") else raw
    body = body[:-1] if body.endswith(b"!") else body
    text = "".join(chr(byte) if byte in _PRINTABLE else f"\\x{byte:02x}" for byte in body)
    return f"<{text}>"
