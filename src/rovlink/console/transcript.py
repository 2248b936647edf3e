"""The console's output lines: what was sent, each reply in words with its frame, debug text.

A line is a list of ``(style, text)`` fragments — the shape prompt_toolkit prints — built here
without prompt_toolkit, so the words can be tested on their own. Styles are class names
(``class:reply``); the app maps them to colours.
"""

from __future__ import annotations

from rovlink.piloting import SentFrame, reply_text
from rovlink.protocol import BadFrame, Event, Frame, Response, Text, encode
from rovlink.protocol.visible import visible

__all__ = [
    "Line",
    "error_line",
    "event_line",
    "info_line",
    "is_notice",
    "late_reply_line",
    "notice_line",
    "plain_text",
    "reply_line",
    "sent_lines",
]

Line = list[tuple[str, str]]

# Replies are padded to this width so their frames line up.
_REPLY_WIDTH = 26


def plain_text(line: Line) -> str:
    """The line without styles.

    >>> plain_text([("class:a", "qd"), ("", " → 1 cm")])
    'qd → 1 cm'
    """
    return "".join(text for _, text in line)


def sent_lines(sent: SentFrame) -> list[Line]:
    """``→ #th.270.25!``, and a warning if the controller will drop it.

    >>> from rovlink.protocol import Command
    >>> [plain_text(line) for line in sent_lines(SentFrame(b"#qd!", Command("qd")))]
    ['  → #qd!']
    """
    lines: list[Line] = [[("class:sent", f"  → {sent.text}")]]
    if sent.command is None:
        lines[0].append(("class:warning", "   not a command the controller takes as it stands"))
    if sent.warning is not None:
        lines.append([("class:warning", f"  ! {sent.warning}")])
    return lines


def reply_line(response: Response, algorithm: str | None = None) -> Line:
    """``qd → 123 cm`` and the frame the controller wrote (with its checksum, if on).

    >>> plain_text(reply_line(Response("qd", (123,)), "crc8"))
    '  qd → 123 cm               $qd.12313!'
    """
    words = reply_text(response)
    style = "class:alarm" if response.name == "q.l" and response.values[0] else "class:reply"
    frame = encode(response, algorithm).decode("ascii")
    # (Words longer than the column, a leak's, keep a gap before the frame all the same.)
    column = max(_REPLY_WIDTH, len(words) + 2)
    return [(style, f"  {words:<{column}}"), ("class:frame", frame)]


def late_reply_line(response: Response, algorithm: str | None = None) -> Line:
    """A reply that came after its query had timed out (P20): shown, never taken as the
    answer to a later query.

    >>> plain_text(late_reply_line(Response("qd", (5,))))
    '  qd → 5 cm                 $qd.5!  late: its query had timed out'
    """
    return [*reply_line(response, algorithm), ("class:warning", "  late: its query had timed out")]


def event_line(event: Event) -> Line:
    """Something from the controller that answered no query: debug text, a dropped frame.

    >>> plain_text(event_line(Text("debug: target depth 100 cm")))
    '  ⋯ debug: target depth 100 cm'
    """
    if isinstance(event, Text):
        return [("class:debug", f"  ⋯ {visible(event.text)}")]
    raw = visible(event.raw.decode("ascii", errors="backslashreplace"))
    if isinstance(event, BadFrame):
        return [("class:warning", f"  dropped from the controller: {raw} ({event.detail})")]
    assert isinstance(event, Frame)
    return [("class:debug", f"  unasked-for reply {raw} (late, or nobody asked)")]


def error_line(text: str) -> Line:
    """An error, e.g. a query that got no reply."""
    return [("class:error", f"  ✗ {text}")]


def info_line(text: str, style: str = "class:info") -> Line:
    """A message of the console itself."""
    return [(style, text)]


def notice_line(text: str) -> Line:
    """A remark of the console's own on what it does (leaving, a line abandoned): not an
    answer to a line."""
    return [("class:notice", text)]


#: The styles that begin a remark of the console's own, not what went out or came back nor
#: the answer to a line (``help``, ``status``).
_NOTICE_STYLES = frozenset({"class:notice", "class:warning", "class:error", "class:stop"})


def is_notice(line: Line) -> bool:
    """Whether ``line`` is the console's own remark (a warning, an error, leaving): what a
    script's output to a file or a pipe leaves to stderr, keeping stdout for what was sent,
    the replies and the controller's own lines.

    >>> is_notice(error_line("#qd!: no reply")), is_notice(reply_line(Response("qd", (5,))))
    (True, False)
    """
    return bool(line) and line[0][0] in _NOTICE_STYLES
