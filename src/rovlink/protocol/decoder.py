"""The streaming decoder: bytes in, events out (PROTOCOL.md P1, P3, P5).

``Decoder.feed`` takes any chunk of a byte stream and returns the events completed by it; feeding
a stream whole, byte by byte or in any other chunks gives the same events. It never raises on its
input, keeps at most one partial frame (at most :data:`MAX_FRAME_BYTES`) and one partial text line
(at most :data:`MAX_TEXT_BYTES`) buffered, and resynchronises on every start character.
"""

from __future__ import annotations

import re

from rovlink.protocol.checksum import (
    CRC8_SMBUS_TABLE,
    DEFAULT_ALGORITHM,
    HEX_DIGITS,
    HEX_DIGITS_END,
    ChecksumAlgorithm,
    crc8_smbus,
    get_algorithm,
)
from rovlink.protocol.commands import COMMANDS, Kind
from rovlink.protocol.frames import (
    CHECKSUM_MODE_FRAMES,
    FAST_ENTRIES,
    MAX_FRAME_BYTES,
    EndedNumberTexts,
    FrameError,
    NumberTexts,
    Reason,
    decode_body,
)
from rovlink.protocol.frozen import frozen
from rovlink.protocol.messages import Message, Response

__all__ = [
    "MAX_TEXT_BYTES",
    "BadFrame",
    "Decoder",
    "Event",
    "Frame",
    "Text",
]

#: A text line longer than this is reported in pieces of this size, so noise cannot grow memory.
MAX_TEXT_BYTES = 256


@frozen
class Frame:
    """A valid frame and the message in it."""

    __slots__ = ("message", "raw")
    __match_args__ = ("message", "raw")

    message: Message
    raw: bytes

    def __init__(self, message: Message, raw: bytes) -> None:
        _set_frame_message(self, message)
        _set_frame_raw(self, raw)


@frozen
class Text:
    """One non-blank line of bytes between frames: debug output or line noise (never a frame)."""

    __slots__ = ("text",)
    __match_args__ = ("text",)

    text: str

    def __init__(self, text: str) -> None:
        object.__setattr__(self, "text", text)


@frozen
class BadFrame:
    """A frame that was dropped, why (:class:`Reason`), and its raw bytes."""

    __slots__ = ("detail", "raw", "reason")
    __match_args__ = ("reason", "raw", "detail")

    reason: Reason
    raw: bytes
    detail: str

    def __init__(self, reason: Reason, raw: bytes, detail: str) -> None:
        _set = object.__setattr__
        _set(self, "reason", reason)
        _set(self, "raw", raw)
        _set(self, "detail", detail)


Event = Frame | Text | BadFrame

_START = re.compile(rb"[#$]")
# Bytes that end a frame's body: the end "!", a start character, or anything not printable.
_BODY_STOP = re.compile(rb"[^\x22\x25-\x7e]")
# A whole frame with nothing odd in it: the common case, taken without the byte-level states.
_WHOLE_FRAME = re.compile(rb"[#$][\x22\x25-\x7e]{0,%d}!" % (MAX_FRAME_BYTES - 2))
#: Whole frames with gaps between some of them are checked in blocks of this many.
_GAP_BLOCK_FRAMES = 64
_LINE_BREAK = re.compile(rb"[\r\n]")
_START_BYTES = frozenset(b"#$")
_COMMAND = Kind.COMMAND
_RESPONSE = Kind.RESPONSE
_MODE_FRAMES = CHECKSUM_MODE_FRAMES
_EXACT_MATCH_BODIES = frozenset(spec.name.encode() for spec in COMMANDS if spec.exact_match)
_HONOURED_BARE_FRAMES = frozenset(
    b"#" + spec.name.encode() + b"!" for spec in COMMANDS if spec.honoured_bare
)
#: Decoded frames remembered per decoder: telemetry repeats itself, and a hit skips the checksum
#: and the parse. Bounded so that a stream of ever-new frames cannot grow memory.
_CACHE_ENTRIES = 512


class Decoder:
    """Incremental decoder for one direction of the link (or a capture of both).

    ``checksum_enabled`` is the current checksum mode; the decoder follows ``#crcon!`` and
    ``#crcoff!`` frames in its own stream (P3) and its owner may set it directly.

    >>> decoder = Decoder()
    >>> [type(event).__name__ for event in decoder.feed(b"boot ok\\r\\n#qd!$qd.12")]
    ['Text', 'Frame']
    >>> decoder.feed(b"3!")[0].message
    Response(name='qd', values=(123,))
    """

    __slots__ = ("_algorithm", "_caches", "_frame", "_skipping", "_text", "checksum_enabled")

    def __init__(
        self,
        *,
        checksum_enabled: bool = False,
        algorithm: str | ChecksumAlgorithm = DEFAULT_ALGORITHM,
    ) -> None:
        self.checksum_enabled = checksum_enabled
        self._algorithm = get_algorithm(algorithm)
        self._frame = b""  # the unfinished frame, start character included
        self._skipping = False  # inside an over-long frame, dropping bytes until it ends
        self._text = b""  # the unfinished text line
        # One cache per checksum mode: the same bytes decode differently in each.
        self._caches: tuple[dict[bytes, Event], dict[bytes, Event]] = ({}, {})

    @property
    def algorithm(self) -> ChecksumAlgorithm:
        """The checksum algorithm used while the checksum mode is on."""
        return self._algorithm

    @algorithm.setter
    def algorithm(self, algorithm: str | ChecksumAlgorithm) -> None:
        self._algorithm = get_algorithm(algorithm)
        for cache in self._caches:
            cache.clear()

    @property
    def buffered_bytes(self) -> int:
        """Bytes of the unfinished frame held until more input arrives (at most 63)."""
        return len(self._frame)

    @property
    def buffered_text_bytes(self) -> int:
        """Bytes of the unfinished text line held until more input arrives."""
        return len(self._text)

    def frame_message(self, data: bytes) -> Message | None:
        """The message of a chunk that is exactly one whole frame carrying values (a reply read
        as it arrives), with nothing buffered: from the cache of frames, or by table lookups
        alone, without making an event. ``None`` for any other chunk, and for anything the
        tables do not hold, which is then left unread: :meth:`feed` it (it decodes, or names
        the problem).

        >>> decoder = Decoder()
        >>> decoder.frame_message(b"$qd.5!")
        Response(name='qd', values=(5,))
        >>> decoder.frame_message(b"$qd.5!$qd.6!") is None   # two frames: feed() them
        True
        """
        if self._frame or self._skipping or self._text or len(data) > MAX_FRAME_BYTES:
            return None  # (an overlong frame is dropped by feed, P1)
        checked = self.checksum_enabled
        event = self._caches[checked].get(data)
        if type(event) is Frame:
            return event.message
        if event is not None or (checked and self._algorithm.function is not crc8_smbus):
            return None  # (what the cache holds of a bad frame; another algorithm's tables)
        # A canonical frame with values: its message is the decoder's (shared by value for a
        # one-value frame), so neither a Frame nor a cache entry is needed to answer a query.
        return _canonical_message(data, checked)

    def reply_message(self, data: bytes, name: str) -> Response | None:
        """:meth:`frame_message` for a chunk expected to be one whole one-value reply of
        ``name`` (the reply a polling loop's query waits for): its message, or ``None`` for
        anything else, when :meth:`frame_message` may still take it. Cheaper than
        :meth:`frame_message` for a reply of a new value: it knows where the value starts.

        >>> decoder = Decoder()
        >>> decoder.reply_message(b"$qd.5!", "qd")
        Response(name='qd', values=(5,))
        >>> decoder.reply_message(b"$qr.5!", "qd") is None
        True
        """
        if self._frame or self._skipping or self._text or len(data) > MAX_FRAME_BYTES:
            return None
        reader = _REPLY_READERS.get(name)
        if reader is None:
            return None
        head, numbers, ended_numbers, crc = reader
        if not data.startswith(head):
            return None
        if not self.checksum_enabled:
            number = ended_numbers[data[len(head) :]]
            return None if number is None else number[3]  # type: ignore[return-value]  # (as below)
        if self._algorithm.function is not crc8_smbus:
            return None
        number = numbers[data[len(head) : len(data) - 3]]  # (two hex digits and the "!" after)
        if number is None or not data.endswith(_HEX_DIGITS_END[number[1][crc] ^ number[2]]):
            return None
        return number[3]  # type: ignore[return-value]  # (a reply's table holds Responses)

    def feed(self, data: bytes) -> list[Event]:
        """Decode another chunk of the stream; return the events it completes."""
        if not (self._frame or self._skipping or self._text):
            # A chunk that is one whole frame seen lately (a reply read as it arrives): no
            # scanning. Mode frames are never cached, so this cannot skip a mode change.
            event = self._caches[self.checksum_enabled].get(data)
            if event is not None:
                return [event]
        events: list[Event] = []
        position = 0
        end = len(data)
        if self._frame or self._skipping:
            position = self._run_states(data, position, end, events, until_idle=True)
        whole_frames = _WHOLE_FRAME.findall(data, position)
        if whole_frames:
            frames_bytes = b"".join(whole_frames)
            if data.startswith(frames_bytes, position):
                # Back-to-back frames, as a controller sends them: no gaps to look at.
                self._begin_frame(events)
                self._add_frames(whole_frames, events)
                position += len(frames_bytes)
            else:
                position = self._feed_with_gaps(data, position, whole_frames, events)
        if position < end:
            self._run_states(data, position, end, events, until_idle=False)
        return events

    def _add_frames(self, whole_frames: list[bytes], events: list[Event]) -> None:
        """Decode whole frames known to stand back to back.

        Every frame of a stream passes here, so the common case is spelled out inline: a frame
        seen lately is taken from the cache; a frame with one or two values in their canonical
        spelling is split by table lookups, its numbers and CRC-8 taken from the tables of
        numbers already met (:class:`NumberTexts`), and its message built directly. Anything
        else (a bare name, a mode frame, another algorithm, any doubt) goes to
        :meth:`_complete`, which names the problem.
        """
        append = events.append
        caches = self._caches
        checked = self.checksum_enabled
        cache = caches[checked]
        # Another algorithm than CRC-8/SMBUS: the fast path would need its CRC tables.
        inline = not checked or self._algorithm.function is crc8_smbus
        for raw in whole_frames:
            event = cache.get(raw)
            if event is not None:
                append(event)
                continue
            message = _canonical_message(raw, checked) if inline else None
            if message is not None:
                event = _new_frame(Frame)
                _set_frame_message(event, message)
                _set_frame_raw(event, raw)
            else:
                event = self._complete(raw)
                if raw in _MODE_FRAMES:  # never cached: each one changes the mode (P3)
                    append(event)
                    checked = self.checksum_enabled
                    cache = caches[checked]
                    inline = not checked or self._algorithm.function is crc8_smbus
                    continue
            if len(cache) >= _CACHE_ENTRIES:
                cache.clear()
            cache[raw] = event
            append(event)

    def _feed_with_gaps(
        self, data: bytes, position: int, whole_frames: list[bytes], events: list[Event]
    ) -> int:
        """The whole frames found from ``position`` on, with text, noise or broken frames
        between some of them: blocks of frames back to back are taken as they are, and only a
        block with a gap is walked frame by frame to find it."""
        run_start = 0  # the first frame of the current run of frames back to back
        for block_start in range(0, len(whole_frames), _GAP_BLOCK_FRAMES):
            block = whole_frames[block_start : block_start + _GAP_BLOCK_FRAMES]
            block_bytes = b"".join(block)
            if data.startswith(block_bytes, position):
                position += len(block_bytes)
                continue
            for index, raw in enumerate(block, block_start):
                if data.startswith(raw, position):
                    position += len(raw)
                    continue
                # The first place from here where the frame's bytes stand is where it was found:
                # the same bytes earlier would have matched there first.
                start = data.index(raw, position)
                self._add_run(whole_frames[run_start:index], events)
                self._run_states(data, position, start, events, until_idle=False)
                run_start = index
                position = start + len(raw)
        self._add_run(whole_frames[run_start:], events)
        return position

    def _add_run(self, frames: list[bytes], events: list[Event]) -> None:
        if frames:
            self._begin_frame(events)  # the run's first start character ends any text line
            self._add_frames(frames, events)

    def end(self) -> list[Event]:
        """The events of the end of the stream: any unfinished text, any truncated frame."""
        events: list[Event] = []
        self._flush_text(events)
        if self._frame:
            events.append(BadFrame(Reason.TRUNCATED, self._frame, "input ended inside a frame"))
            self._frame = b""
        self._skipping = False
        return events

    def reset(self) -> None:
        """Forget any partial frame or text (the checksum mode is kept)."""
        self._frame = b""
        self._text = b""
        self._skipping = False

    # -- the byte-level states, for everything but whole clean frames ---------------------

    def _run_states(
        self, data: bytes, position: int, end: int, events: list[Event], *, until_idle: bool
    ) -> int:
        """Run the states over ``data[position:end]``; with ``until_idle``, stop once no frame
        is open, so that the caller can take the rest on the fast path."""
        while position < end:
            if self._frame:
                position = self._continue_frame(data, position, end, events)
            elif self._skipping:
                position = self._skip_overlong(data, position, end)
            elif until_idle:
                break
            else:
                position = self._read_text(data, position, end, events)
        return position

    def _read_text(self, data: bytes, position: int, end: int, events: list[Event]) -> int:
        match = _START.search(data, position, end)
        stop = match.start() if match else end
        if stop > position:
            self._add_text(data[position:stop], events)
        if match is None:
            return stop
        self._begin_frame(events)
        self._frame = data[stop : stop + 1]
        return stop + 1

    def _continue_frame(self, data: bytes, position: int, end: int, events: list[Event]) -> int:
        match = _BODY_STOP.search(data, position, end)
        stop = match.start() if match else end
        room = MAX_FRAME_BYTES - 1 - len(self._frame)  # the end "!" needs one byte too
        if stop - position > room:
            overlong = self._frame + data[position : position + room + 1]
            events.append(
                BadFrame(Reason.TOO_LONG, overlong, f"frame longer than {MAX_FRAME_BYTES} bytes")
            )
            self._frame = b""
            self._skipping = True
            return position + room + 1
        if match is None:
            self._frame += data[position:end]
            return end
        frame = self._frame + data[position:stop]
        byte = data[stop]
        if byte == 0x21:  # "!"
            self._frame = b""
            events.append(self._complete(frame + b"!"))
            return stop + 1
        if byte in _START_BYTES:
            self._frame = frame
            self._begin_frame(events)  # the start character abandons this frame ...
            self._frame = data[stop : stop + 1]  # ... and begins the next
            return stop + 1
        self._frame = b""
        events.append(BadFrame(Reason.MALFORMED, frame, f"byte 0x{byte:02x} inside a frame"))
        return stop  # the byte is between frames now: text or a line break

    def _skip_overlong(self, data: bytes, position: int, end: int) -> int:
        match = _BODY_STOP.search(data, position, end)
        if match is None:
            return end
        self._skipping = False
        stop = match.start()
        return stop + 1 if data[stop] == 0x21 else stop

    def _begin_frame(self, events: list[Event]) -> None:
        """A start character arrived: it ends any text line and abandons any open frame (P1)."""
        if self._frame:
            events.append(
                BadFrame(
                    Reason.MALFORMED, self._frame, "frame interrupted by a new start character"
                )
            )
            self._frame = b""
        self._skipping = False
        self._flush_text(events)

    # -- text -----------------------------------------------------------------------------

    def _add_text(self, chunk: bytes, events: list[Event]) -> None:
        pieces = _LINE_BREAK.split(chunk)
        last = len(pieces) - 1
        for index, piece in enumerate(pieces):
            self._text += piece
            while len(self._text) >= MAX_TEXT_BYTES:
                self._emit_text(self._text[:MAX_TEXT_BYTES], events)
                self._text = self._text[MAX_TEXT_BYTES:]
            if index < last:  # the piece ended at a line break
                self._flush_text(events)

    def _flush_text(self, events: list[Event]) -> None:
        if self._text:
            self._emit_text(self._text, events)
            self._text = b""

    @staticmethod
    def _emit_text(line: bytes, events: list[Event]) -> None:
        line = line.strip()
        if line:
            events.append(Text(line.decode("utf-8", errors="replace")))

    # -- frames ---------------------------------------------------------------------------

    def _complete(self, frame: bytes) -> Event:
        # Spelled out in one method, with no calls that can be avoided: every new frame comes here.
        if frame[0] == 0x23:  # "#"
            kind = _COMMAND
            mode = _MODE_FRAMES.get(frame)
            if mode is not None:
                self.checksum_enabled = mode
                checked = False
            else:
                checked = self.checksum_enabled and frame not in _HONOURED_BARE_FRAMES
        else:
            kind = _RESPONSE
            checked = self.checksum_enabled
        if checked:
            digits = frame[-3:-1]
            body = frame[1:-3]
            if self._algorithm.function is crc8_smbus and body:  # the default, inline
                crc = 0
                for byte in body:
                    crc = CRC8_SMBUS_TABLE[crc ^ byte]
                expected = HEX_DIGITS[crc]
                verified = digits == expected or digits.upper() == expected
            else:
                verified = bool(body) and self._algorithm.verify(body, digits)
            if not verified:
                return BadFrame(
                    Reason.CHECKSUM, frame, f"missing or wrong {self._algorithm.name} checksum"
                )
            if kind is _COMMAND and body in _EXACT_MATCH_BODIES:
                # "#crcoff3F!" is not "#crcoff!": taking it would report a mode change that the
                # exact-match rule says did not happen (P3).
                return BadFrame(
                    Reason.MALFORMED, frame, f"{body.decode()} never carries a checksum"
                )
        else:
            body = frame[1:-1]
            if not body:
                return BadFrame(Reason.MALFORMED, frame, "empty frame")
        try:
            message = decode_body(kind, body)
        except FrameError as error:
            return BadFrame(error.reason, frame, error.detail)
        event = _new_frame(Frame)  # made as trusted_message makes messages: the hot path
        _set_frame_message(event, message)
        _set_frame_raw(event, frame)
        return event


_new_frame = object.__new__
_set_frame_message = Frame.__dict__["message"].__set__
_set_frame_raw = Frame.__dict__["raw"].__set__
# Messages of values just checked against their spec are made as trusted_message makes them.
_new_message = object.__new__
_set_message_name = Message.__dict__["name"].__set__
_set_message_values = Message.__dict__["values"].__set__
_set_message_spec = Message.__dict__["spec"].__set__
_FAST_ENTRIES = FAST_ENTRIES
_HEX_DIGITS_END = HEX_DIGITS_END
#: The CRC-8/SMBUS register after a "." from each state: the dot between two values.
_DOT_CRC = bytes(CRC8_SMBUS_TABLE[state ^ 0x2E] for state in range(256))


def _reply_readers() -> dict[str, tuple[bytes, NumberTexts, EndedNumberTexts, int]]:
    """For each one-value reply, what :meth:`Decoder.reply_message` needs: the frame's start up
    to its value (``b"$qd."``), the value's numbers without and with the end ``!``, and the
    CRC-8/SMBUS of the name and its ".". Taken from the fast path's own tables, so that both
    paths read a frame alike and share its messages."""
    readers = {}
    for head, entry in _FAST_ENTRIES.items():
        spec, _, _, name_rest, _, last_numbers, last_end, crc = entry
        start = head + b"." + (name_rest + b"." if name_rest else b"")
        if spec.kind is not Kind.RESPONSE or len(spec.arguments) != 1:
            continue
        if start[1:-1] != spec.name.encode():
            continue  # another spelling of the name: a reply is written in its own
        readers[spec.name] = (start, last_numbers, last_end, crc)
    return readers


_REPLY_READERS = _reply_readers()


def _canonical_message(raw: bytes, checked: bool) -> Message | None:
    """The message of a whole frame in its canonical spelling, with in-range values that the
    tables of numbers already met hold (:class:`NumberTexts`), by table lookups alone; ``None``
    for anything else, which the full parser then reads and names the problem of. With
    ``checked``, the frame's CRC-8/SMBUS is checked, continued across the known pieces.

    Only a frame that stands whole gets a message: every piece between the start character
    and the ``!`` is matched exactly, so a chunk of anything else is never taken for a frame.
    """
    message: Message | None = None
    parts = raw.split(b".")
    entry = _FAST_ENTRIES.get(parts[0])
    if entry is not None:
        spec, cls, part_count, name_rest, numbers, last_numbers, last_end, crc = entry
        if len(parts) == part_count:
            # A number: (value, zero-shift table of its length, CRC of its text,
            # message of a one-value spec); the CRC goes on from the name's.
            last = last_numbers[parts[-1][:-3]] if checked else last_end[parts[-1]]
            if last is None:
                pass
            elif part_count == 2 or name_rest:  # one value: its message is made
                if name_rest and parts[1] != name_rest:
                    pass
                elif not checked or raw.endswith(_HEX_DIGITS_END[last[1][crc] ^ last[2]]):
                    message = last[3]
            else:
                first = numbers[parts[1]]
                if first is not None and (
                    not checked
                    or raw.endswith(
                        _HEX_DIGITS_END[last[1][_DOT_CRC[first[1][crc] ^ first[2]]] ^ last[2]]
                    )
                ):
                    message = _new_message(cls)
                    _set_message_name(message, spec.name)
                    _set_message_values(message, (first[0], last[0]))
                    _set_message_spec(message, spec)
    return message
