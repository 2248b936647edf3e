"""``rovlink decode``: read a captured byte stream and print its events as JSON lines."""

from __future__ import annotations

import json
import sys
from collections import Counter
from pathlib import Path
from typing import BinaryIO

import typer

from rovlink.cli.link_options import AlgorithmOption
from rovlink.protocol import DEFAULT_ALGORITHM, BadFrame, Decoder, Event, Frame, Kind, Text

__all__ = ["StreamStats", "decode_stream", "event_to_json", "register"]

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


def _events(stream: BinaryIO, decoder: Decoder) -> list[Event] | None:
    chunk = stream.read(_READ_CHUNK_BYTES)
    if not chunk:
        return None
    return decoder.feed(chunk)


class StreamStats:
    """Counts of a stream's events: per event kind, per error reason, per frame kind and name."""

    def __init__(self) -> None:
        self.events: Counter[str] = Counter()
        self.reasons: Counter[str] = Counter()
        self.names: dict[Kind, Counter[str]] = {kind: Counter() for kind in Kind}

    def count(self, events: list[Event]) -> None:
        """Add ``events`` to the counts."""
        events_seen, names = self.events, self.names
        for event in events:
            if type(event) is Frame:
                events_seen["frame"] += 1
                message = event.message
                names[message.kind][message.name] += 1
            elif type(event) is Text:
                events_seen["text"] += 1
            else:
                assert isinstance(event, BadFrame)
                events_seen["error"] += 1
                self.reasons[event.reason.value] += 1

    def summary(self) -> dict[str, object]:
        """The counts as ``rovlink decode --stats`` prints them."""
        return {
            "events": dict(sorted(self.events.items())),
            "reasons": dict(sorted(self.reasons.items())),
            "names": {kind.value: dict(sorted(counter.items()))
                      for kind, counter in self.names.items()},
        }


def decode_stream(stream: BinaryIO, decoder: Decoder, *, stats_only: bool) -> None:
    """Decode ``stream`` to the end, printing JSON lines (or one summary with ``stats_only``)."""
    stats = StreamStats()
    write = sys.stdout.write
    while True:
        events = _events(stream, decoder)
        last = events is None
        if events is None:
            events = decoder.end()
        if stats_only:
            stats.count(events)
        else:
            for event in events:
                write(json.dumps(event_to_json(event), ensure_ascii=False) + "\n")
        if last:
            break
    if stats_only:
        write(json.dumps(stats.summary()) + "\n")


def register(app: typer.Typer) -> None:
    """Add ``decode`` to the command line."""

    @app.command()
    def decode(
        file: Path | None = typer.Argument(
            None, help="A capture of the byte stream; standard input when omitted.",
            exists=True, dir_okay=False, readable=True,
        ),
        checksum: bool = typer.Option(
            False, "--checksum", help="Start in checksum mode (as after #crcon!)."
        ),
        algorithm: AlgorithmOption = DEFAULT_ALGORITHM,
        stats: bool = typer.Option(
            False, "--stats", help="Print one JSON summary of counts instead of the events."
        ),
    ) -> None:
        """Decode a captured byte stream: one JSON object per line per event."""
        decoder = Decoder(checksum_enabled=checksum, algorithm=algorithm)
        if file is None:
            decode_stream(sys.stdin.buffer, decoder, stats_only=stats)
        else:
            with file.open("rb") as stream:
                decode_stream(stream, decoder, stats_only=stats)
