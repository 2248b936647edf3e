"""Decode a captured byte stream: one JSON object per line per event (or, with --stats, one
summary of counts). Errors in the stream are events, never a failure of the command."""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import Counter
from itertools import compress, repeat
from operator import attrgetter, is_

from rovlink.cli.failure import CommandError, reason
from rovlink.cli.link_options import add_checksum_options
from rovlink.protocol import BadFrame, Decoder, Event, Frame, Kind, Message, Text

# Not typing's: it would cost a fifth of this command's start-up.
TYPE_CHECKING = False

if TYPE_CHECKING:
    from typing import BinaryIO

__all__ = ["EPILOG", "StreamStats", "decode_stream", "event_to_json"]

# json escapes C0 controls but passes DEL and C1 (0x9b is a one-character CSI to some
# terminals): escaped too, so that line noise in a capture cannot drive the reader's terminal.
# (re is loaded by json already: no start-up cost.)
_DEL_AND_C1 = re.compile("[\x7f-\x9f]")


def _json_escape(match: re.Match[str]) -> str:
    return f"\\u{ord(match.group()):04x}"


# A pipe's capacity: a live pipe never has more waiting, and a file decodes faster in chunks
# that stay in the processor's caches than in megabytes.
_READ_CHUNK_BYTES = 1 << 16


def event_to_json(event: Event) -> dict[str, object]:
    """The JSON object of one decoder event, as ``rovlink decode`` prints it."""
    if isinstance(event, Frame):
        message = event.message
        return {
            "event": "frame",
            "kind": message.kind.value,
            "name": message.name,
            "values": list(message.values),
            "raw": event.raw.decode("ascii"),
        }
    if isinstance(event, Text):
        return {"event": "text", "text": event.text}
    return {
        "event": "error",
        "reason": event.reason.value,
        "raw": event.raw.decode("latin-1"),
        "detail": event.detail,
    }


class _ReadError(Exception):
    """Reading the input failed (a directory, a device error): not a failure to write stdout."""

    def __init__(self, error: OSError) -> None:
        super().__init__(reason(error))


def _events(stream: BinaryIO, decoder: Decoder) -> list[Event] | None:
    # read1: whatever is there, up to a chunk, so that a live pipe is decoded as it comes.
    read = getattr(stream, "read1", stream.read)
    try:
        chunk = read(_READ_CHUNK_BYTES)
    except OSError as error:
        raise _ReadError(error) from None
    if not chunk:
        return None
    return decoder.feed(chunk)


_EVENT_NAMES = {Frame: "frame", Text: "text", BadFrame: "error"}
_message_of = attrgetter("message")
_name_of = attrgetter("name")
_reason_value_of = attrgetter("reason.value")


class StreamStats:
    """Counts of a stream's events: per event kind, per error reason, per frame kind and name.

    A chunk's events are counted in C (``Counter.update`` over ``map``, ``compress`` and
    ``attrgetter``), never one by one in Python: ``decode --stats`` costs a fraction of the
    decoding, whether the stream repeats itself or every frame is new.
    """

    def __init__(self) -> None:
        self._types: Counter[type] = Counter()
        self._names: Counter[tuple[type[Message], str]] = Counter()
        self.reasons: Counter[str] = Counter()

    def count(self, events: list[Event]) -> None:
        """Add ``events`` to the counts."""
        kinds = list(map(type, events))
        self._types.update(kinds)
        messages = list(map(_message_of, compress(events, map(is_, kinds, repeat(Frame)))))
        self._names.update(zip(map(type, messages), map(_name_of, messages), strict=True))
        if len(messages) < len(events):  # text or errors (rare): the errors' reasons
            bad_frames = compress(events, map(is_, kinds, repeat(BadFrame)))
            self.reasons.update(map(_reason_value_of, bad_frames))

    @property
    def events(self) -> dict[str, int]:
        """Events per kind: ``frame``, ``text``, ``error``."""
        return {_EVENT_NAMES[kind]: count for kind, count in self._types.items() if count}

    @property
    def names(self) -> dict[Kind, Counter[str]]:
        """Frames per kind (command, response) and name."""
        names: dict[Kind, Counter[str]] = {kind: Counter() for kind in Kind}
        for (message_class, name), count in self._names.items():
            names[message_class.kind][name] += count
        return names

    def summary(self) -> dict[str, object]:
        """The counts as ``rovlink decode --stats`` prints them."""
        return {
            "events": dict(sorted(self.events.items())),
            "reasons": dict(sorted(self.reasons.items())),
            "names": {
                kind.value: dict(sorted(counter.items())) for kind, counter in self.names.items()
            },
        }


def _write_json(shown: dict[str, object]) -> None:
    """One JSON object per line, with DEL and C1 controls escaped (a terminal may act on them)."""
    line = json.dumps(shown, ensure_ascii=False)
    try:
        sys.stdout.write(_DEL_AND_C1.sub(_json_escape, line) + "\n")
    except UnicodeEncodeError:  # an output that is not UTF-8 (nothing of the line was written)
        sys.stdout.write(_DEL_AND_C1.sub(_json_escape, json.dumps(shown)) + "\n")


def decode_stream(stream: BinaryIO, decoder: Decoder, *, stats_only: bool) -> None:
    """Decode ``stream`` to the end, printing JSON lines (or one summary with ``stats_only``)."""
    stats = StreamStats()
    while True:
        events = _events(stream, decoder)
        last = events is None
        if events is None:
            events = decoder.end()
        if stats_only:
            stats.count(events)
        else:
            for event in events:
                _write_json(event_to_json(event))
            sys.stdout.flush()  # a chunk at a time: a live pipe's events show as they come
        if last:
            break
    if stats_only:
        _write_json(stats.summary())


EPILOG = """\
examples:
  rovlink decode capture.bin
  socat -u /dev/ttyUSB0,raw,b115200 - | rovlink decode --checksum
  rovlink decode --stats --checksum --algorithm xor capture.bin"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``decode``'s arguments."""
    parser.add_argument(
        "file",
        metavar="FILE",
        nargs="?",
        default="-",
        help="a capture of the byte stream, or a recording (.mcap, .jsonl: its raw wire); "
        "'-' or none: standard input",
    )
    add_checksum_options(
        parser, "start in checksum mode, as after #crcon! (a recording: as its header says)"
    )
    # Not given: a recording starts in the mode its header records, a capture with it off.
    parser.set_defaults(checksum=None)
    parser.add_argument(
        "--stats",
        action="store_true",
        help="print one JSON summary of counts instead of the events",
    )


def run(args: argparse.Namespace) -> int:
    """Decode the file (or standard input) to the end (a reader that stops early, ``| head``,
    is no error: see ``rovlink.cli.main``)."""
    decoder = Decoder(checksum_enabled=bool(args.checksum), algorithm=args.algorithm)
    if args.file == "-":
        if sys.stdin is None:  # (started with it closed: <&-)
            raise CommandError("cannot read standard input: closed")
        try:
            decode_stream(sys.stdin.buffer, decoder, stats_only=args.stats)
        except _ReadError as error:
            raise CommandError(f"cannot read standard input: {error}") from None
        return 0
    if args.file.lower().endswith((".mcap", ".jsonl")):
        return _decode_recording(args)
    if args.file.lower().endswith(".csv") and _is_telemetry_table(args.file):
        raise CommandError(
            f"{args.file} holds only the telemetry table, not the wire: rovlink plot {args.file}"
        )
    try:
        stream = open(args.file, "rb")  # noqa: SIM115 - closed below, after the error handling
    except OSError as error:
        raise CommandError(f"cannot read {args.file}: {reason(error)}") from None
    with stream:
        try:
            decode_stream(stream, decoder, stats_only=args.stats)
        except _ReadError as error:  # a directory, a device error
            raise CommandError(f"cannot read {args.file}: {error}") from None
    return 0


def _is_telemetry_table(path: str) -> bool:
    """Whether ``path`` starts with the header of a recording's telemetry CSV (any other
    ``.csv`` is decoded as a capture: some save theirs under that name)."""
    from rovlink.recorder.csv_format import HEADER, UNENDED_HEADER  # noqa: PLC0415

    try:
        with open(path, "rb") as stream:
            first_line = stream.readline(4096)
    except OSError:
        return False  # said by the capture's own open, with the reason
    return first_line.rstrip(b"\r\n") in (
        ",".join(HEADER).encode(),
        ",".join(UNENDED_HEADER).encode(),
    )


def _decode_recording(args: argparse.Namespace) -> int:
    """A recording's wire channel, each direction decoded as its end reads it (a reply in
    its query's checksum mode, P3), with the link's own events (``lost``, ``reconnected``:
    where a gap is); damage is reported after it."""
    from rovlink.recorder import RecordingDamagedError, RecordingError, read_entries  # noqa: PLC0415
    from rovlink.recorder.entries import EventEntry, HeaderEntry, WireEntry  # noqa: PLC0415
    from rovlink.recorder.link_decoding import LinkDecoder  # noqa: PLC0415

    link = LinkDecoder(checksum=bool(args.checksum), algorithm=args.algorithm)
    checksum_given = args.checksum is not None
    algorithm_given = getattr(args, "algorithm_given", False)
    stats = StreamStats()
    damage: RecordingDamagedError | None = None

    def show(direction: str, decoded: list[tuple[Event, str | None]]) -> None:
        events = [event for event, _ in decoded]
        if args.stats:
            stats.count(events)
            return
        for event, query in decoded:
            shown: dict[str, object] = {"direction": direction, **event_to_json(event)}
            if query is not None:
                shown["query"] = query
            _write_json(shown)
        sys.stdout.flush()

    try:
        try:
            for entry in read_entries(args.file):
                if isinstance(entry, WireEntry):
                    show(entry.direction, link.feed(entry.direction, entry.data))
                elif isinstance(entry, EventEntry) and entry.event == "link" and not args.stats:
                    _write_json({"event": "link", "state": entry.name, "detail": entry.detail})
                elif isinstance(entry, HeaderEntry) and not (checksum_given and algorithm_given):
                    # The mode and algorithm the link was in as this file starts (each file of
                    # a rotation records its own), each unless the command line says otherwise.
                    try:
                        link.set_mode(
                            args.checksum if checksum_given else entry.checksum,
                            args.algorithm if algorithm_given else entry.algorithm,
                        )
                    except ValueError as error:  # (a header damaged, or from a newer version)
                        raise CommandError(f"{args.file}: the header's {error}") from None
        except RecordingDamagedError as error:
            damage = error
    except RecordingError as error:
        raise CommandError(str(error)) from None
    for direction, event in link.end():
        show(direction, [(event, None)])
    if args.stats:
        _write_json(stats.summary())
    if damage is not None:
        print(f"rovlink decode: {damage}", file=sys.stderr)
        return 0 if damage.incomplete else 1
    return 0
