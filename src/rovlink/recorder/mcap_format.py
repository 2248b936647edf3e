"""``.mcap``: the default format, one channel per kind of entry, JSON messages with JSON Schemas.

Foxglove opens it as it is and plots ``/rovlink/telemetry.depth_cm`` with no plugin. The file is
chunked (zstd) and indexed by the ``mcap`` library. The recorder closes a chunk every second,
so a recorder killed mid-dive leaves every chunk before its last second readable; the reader
here reads such a file up to where it stops (the index at the end is missing then, which
only slows seeking).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from typing import BinaryIO, cast

from mcap.records import Channel, Header, Message
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

import rovlink
from rovlink.recorder.entries import CHANNELS, Entry, EntryError, entry_from_json
from rovlink.recorder.sink import FileSink, RecordingDamagedError, RecordingError, open_recording

__all__ = ["PROFILE", "TOPIC_PREFIX", "McapSink", "read_mcap"]

#: The MCAP profile (the header names it; the channels are rovlink's own, JSON-encoded).
PROFILE = "rovlink"
#: Each channel's topic is this prefix and the channel's name: ``/rovlink/telemetry``.
TOPIC_PREFIX = "/rovlink/"
#: How every MCAP file starts.
_MAGIC = b"\x89MCAP0\r\n"
# A record larger than this is damage, not data: no entry of ours comes near it.
_RECORD_SIZE_LIMIT = 64 << 20


class _PositionCounted:
    """A pipe, with the position the MCAP writer asks for as it indexes its chunks (a pipe has
    none of its own: ``tell`` fails with "Illegal seek")."""

    def __init__(self, stream: BinaryIO) -> None:
        self._stream = stream
        self._position = 0

    def write(self, data: bytes) -> int:
        written = self._stream.write(data)
        self._position += len(data)
        return written

    def tell(self) -> int:
        return self._position

    def flush(self) -> None:
        self._stream.flush()


class McapSink(FileSink):
    """Writes entries as MCAP messages."""

    unit = "messages"

    def __init__(self, path: str) -> None:
        super().__init__(path)
        stream = self._file if self._on_disk else cast("BinaryIO", _PositionCounted(self._file))
        self._writer = Writer(stream)
        self._writer.start(profile=PROFILE, library=f"rovlink {rovlink.__version__}")
        self._channel_ids: dict[str, int] = {}
        for channel, schema in CHANNELS.items():
            schema_id = self._writer.register_schema(
                name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode()
            )
            self._channel_ids[channel] = self._writer.register_channel(
                topic=TOPIC_PREFIX + channel, message_encoding="json", schema_id=schema_id
            )
        self._sequence = 0

    def write(self, entry: Entry) -> None:
        self._sequence += 1
        self._writer.add_message(
            channel_id=self._channel_ids[entry.channel],
            log_time=entry.wall_ns,
            publish_time=entry.wall_ns,
            sequence=self._sequence,
            data=json.dumps(entry.to_json(), separators=(",", ":")).encode(),
        )
        self._written += 1

    def flush(self) -> None:
        self._writer.flush()  # type: ignore[no-untyped-call] # the chunk in progress is written
        super().flush()

    def close(self) -> None:
        if not self._file.closed:
            try:
                self._writer.finish()  # type: ignore[no-untyped-call]
            except BaseException:
                self._written = self._durable  # the messages since the last flush: not whole
                raise
            finally:  # a full disk fails the index: the file is closed all the same
                super().close()


def read_mcap(path: str) -> Iterator[Entry]:
    """The entries of a ``.mcap`` recording, in the order they were written."""
    stream = open_recording(path)
    count = 0
    channels: dict[int, str] = {}
    profile = ""  # whose MCAP file it is: a ROS bag's says "ros2"
    with stream:
        head = stream.read(len(_MAGIC))
        stream.seek(0)
        reader = StreamReader(stream, validate_crcs=True, record_size_limit=_RECORD_SIZE_LIMIT)
        records = iter(reader.records)
        while True:
            try:
                record = next(records, None)
            # A damaged file can make the library fail anywhere (a decompressor's error, a
            # short unpack, a bad record length): each is damage at this point of the file.
            except Exception as error:
                if count == 0 and not channels and not _MAGIC.startswith(head):
                    # (The library's own words, "unpack requires a buffer of 8 bytes", say
                    # nothing to whoever gave the file.)
                    raise RecordingError(
                        f"{path}: not an MCAP recording (it does not start with MCAP's magic "
                        "bytes: another kind of file named .mcap)"
                    ) from None
                # (An empty file, or one cut after its first bytes, is a recorder killed before
                # its first second: a recording that ends early, as any other.)
                if not head:
                    raise RecordingDamagedError.empty(path) from None
                raise _damage(path, error, count) from None
            if record is None:
                if not channels:  # (ours are written first, before any message)
                    raise RecordingError(_foreign(path, profile))
                return
            if isinstance(record, Header):
                profile = record.profile
            elif isinstance(record, Channel):
                if record.topic.startswith(TOPIC_PREFIX):
                    channels[record.id] = record.topic[len(TOPIC_PREFIX) :]
            elif isinstance(record, Message) and record.channel_id in channels:
                try:
                    entry = entry_from_json(channels[record.channel_id], json.loads(record.data))
                except (ValueError, EntryError) as error:
                    raise RecordingDamagedError(
                        f"{path}: message {count + 1} is damaged ({error}); read {count} "
                        "entries before it",
                        entries_read=count,
                        incomplete=False,
                    ) from None
                count += 1
                yield entry


def _foreign(path: str, profile: str) -> str:
    """What an MCAP file of another program is not (its profile says whose it is, if any)."""
    whose = f" (profile {profile!r})" if profile else ""
    return f"{path}: not a rovlink recording: an MCAP file{whose} with no {TOPIC_PREFIX}… topics"


def _damage(path: str, error: Exception, count: int) -> RecordingDamagedError:
    name = type(error).__name__
    # The reader meets the end of a cut file as its own EndOfFile or as too few bytes to unpack.
    if name == "EndOfFile" or isinstance(error, EOFError | struct.error):
        return RecordingDamagedError(
            f"{path}: the recording ends early, without its index (its recorder was stopped "
            f"abruptly); read {count} entries",
            entries_read=count,
            incomplete=True,
        )
    detail = f"{name}: {error}" if str(error) else name
    return RecordingDamagedError(
        f"{path}: damaged after {count} entries ({detail})",
        entries_read=count,
        incomplete=False,
    )
