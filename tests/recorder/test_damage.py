"""Crash safety and bad files: a recorder killed with SIGKILL leaves its file readable up to its
last second; truncated, corrupted and foreign files get a clear error after what is readable;
a disk that fills up stops the recording, never the link."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

import rovlink
from rovlink.recorder import (
    Entry,
    EventEntry,
    FrameEntry,
    HeaderEntry,
    Recorder,
    RecordingDamagedError,
    RecordingError,
    WireEntry,
    read_entries,
    rotated_path,
)
from rovlink.recorder.csv_format import UNENDED_HEADER, TelemetryCsvSink
from rovlink.recorder.entries import FORMAT_VERSION, TELEMETRY_FIELDS, TelemetryEntry
from rovlink.recorder.formats import open_sink
from rovlink.recorder.jsonl_format import JsonLinesSink
from tests.recorder.conftest import MakeRecording

_SRC = str(Path(__file__).resolve().parents[2] / "src")

_FEEDER = textwrap.dedent(
    """
    import sys, time
    from rovlink.recorder import Recorder
    recorder = Recorder(sys.argv[1], url="tap")
    while True:
        now = time.monotonic()
        recorder.on_bytes("in", b"$qd.123!", at_s=now)
        print(repr(now), flush=True)
        time.sleep(0.01)
    """
)


def _read_all(path: str) -> tuple[list[Entry], RecordingDamagedError | None]:
    entries: list[Entry] = []
    try:
        for entry in read_entries(path):
            entries.append(entry)
    except RecordingDamagedError as error:
        return entries, error
    return entries, None


@pytest.mark.integration
@pytest.mark.parametrize("suffix", [".mcap", ".jsonl"])
def test_sigkill_leaves_everything_but_the_last_second(tmp_path: Path, suffix: str) -> None:
    path = str(tmp_path / f"killed{suffix}")
    environment = {**os.environ, "PYTHONPATH": _SRC}
    process = subprocess.Popen(
        [sys.executable, "-c", _FEEDER, path], stdout=subprocess.PIPE, text=True, env=environment
    )
    assert process.stdout is not None
    first = float(process.stdout.readline())
    last = first
    while last - first < 3.0:  # three seconds of bytes handed to the recorder
        last = float(process.stdout.readline())
    os.kill(process.pid, signal.SIGKILL)
    process.wait(timeout=10)
    entries, damage = _read_all(path)
    if suffix == ".mcap":  # it has an index at its end, which is missing
        assert damage is not None
        assert damage.incomplete
        assert "ends early" in str(damage)
    else:  # JSON lines: cut in a line, or between two without the closing line
        assert damage is not None
        assert damage.incomplete
        assert "ends early" in str(damage) or "ends in the middle of line" in str(damage)
    wire = [entry for entry in entries if isinstance(entry, WireEntry)]
    assert wire
    assert wire[0].t_s == pytest.approx(first)
    # Flushed every second: at most the last second (plus a loaded machine's lag) is lost.
    assert wire[-1].t_s >= last - 2.0


def test_a_truncated_mcap_is_read_up_to_the_cut(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A chunk is closed on each flush: every 100 ms here, not each second.
    monkeypatch.setattr("rovlink.recorder.recorder.FLUSH_INTERVAL_S", 0.1)
    path = str(tmp_path / "dive.mcap")
    recorder = Recorder(path)  # several chunks
    with recorder, rovlink.connect("sim://?seed=1", on_event=recorder.on_event) as rov:
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            rov.sensors()
    whole = Path(path).read_bytes()
    Path(path).write_bytes(whole[: len(whole) // 2])
    entries, damage = _read_all(path)
    assert damage is not None
    assert damage.incomplete
    assert path in str(damage)
    assert 0 < len(entries) == damage.entries_read < recorder.entries_written


def test_a_corrupted_jsonl_line_is_named(make_recording: MakeRecording) -> None:
    recorder = make_recording("dive.jsonl")
    lines = Path(recorder.path).read_bytes().splitlines(keepends=True)
    lines[10] = b'{"channel": "frames", "t_s": "soon"}\n'
    Path(recorder.path).write_bytes(b"".join(lines))
    entries, damage = _read_all(recorder.path)
    assert damage is not None
    assert not damage.incomplete
    assert "line 11 is damaged" in str(damage)
    assert recorder.path in str(damage)
    assert len(entries) == 10


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl"])
@pytest.mark.parametrize(
    ("direction", "kind", "name", "values", "reason"),
    [
        ("out", "command", "nosuch", (), "unknown command 'nosuch'"),
        ("out", "command", "th", (999, 5), "th: direction_deg must be in 0–360, got 999"),
        ("out", "command", "th", (), "th takes 2 value(s)"),
        ("in", "response", "zz", (), "unknown response 'zz'"),
        ("in", "command", "qd", (), "a 'command' going 'in'"),
    ],
    ids=["unknown-command", "out-of-range", "too-few-values", "unknown-response", "command-in"],
)
def test_a_frame_the_command_table_refuses_is_named_as_damage(
    tmp_path: Path,
    suffix: str,
    direction: str,
    kind: str,
    name: str,
    values: tuple[int, ...],
    reason: str,
) -> None:
    # Every reader's consumer (replay, its --to, plot, decode) builds protocol messages from the
    # frames it reads: one the command table refuses is damage, not a crash there.
    path = str(tmp_path / f"refused{suffix}")
    sink = open_sink(path)
    sink.write(HeaderEntry(1.0, 1, "sim://", False, "crc8", "test", "0"))
    sink.write(FrameEntry(2.0, 2, direction, kind, name, values))
    sink.close()
    entries, damage = _read_all(path)
    assert damage is not None
    assert not damage.incomplete
    assert f"is damaged (frame entry: {reason}" in str(damage)
    assert path in str(damage)
    assert len(entries) == 1


_REPLY = FrameEntry(2.0, 2, "in", "response", "qd", (5,), query="qd", round_trip_ms=1.5)


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl"])
@pytest.mark.parametrize(
    ("entry", "field", "value", "reason"),
    [
        (_REPLY, "round_trip_ms", "x", "frames entry: round_trip_ms must be a number or null"),
        (_REPLY, "direction", "up", "frames entry: direction must be one of 'out', 'in'"),
        (_REPLY, "late", 0, "frames entry: late must be a boolean, got 0"),
        (EventEntry(2.0, 2, "lock", "start"), "event", 5, "events entry: event must be a string"),
        (WireEntry(2.0, 2, "out", b"#qd!"), "by_session", 1, "wire entry: by_session must be a"),
        (WireEntry(2.0, 2, "out", b"#qd!"), "t_s", math.inf, "wire entry: t_s must be a finite"),
    ],
    ids=["round-trip", "direction", "late", "event", "by-session", "infinite time"],
)
def test_a_value_of_another_type_than_its_schema_is_named_as_damage(
    tmp_path: Path, suffix: str, entry: Entry, field: str, value: object, reason: str
) -> None:
    # The readers checked the clocks and the values alone: a round trip of "x" or an event
    # named 5 ended the tools printing them with a traceback.
    path = str(tmp_path / f"mistyped{suffix}")
    sink = open_sink(path)
    sink.write(HeaderEntry(1.0, 1, "sim://", False, "crc8", "test", "0"))
    sink.write(dataclasses.replace(entry, **{field: value}))  # type: ignore[arg-type]
    sink.close()
    entries, damage = _read_all(path)
    assert damage is not None
    assert not damage.incomplete
    assert f"is damaged ({reason}" in str(damage)
    assert len(entries) == 1


@pytest.mark.parametrize("name", ["foreign.mcap", "foreign.jsonl", "foreign.csv"])
def test_a_foreign_file_is_refused_by_name(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_bytes(b"PK\x03\x04 this is a zip file, not a recording\n")
    with pytest.raises(RecordingError, match=name) as caught:
        list(read_entries(str(path)))
    assert not isinstance(caught.value, RecordingDamagedError)


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="No such file"):
        list(read_entries(str(tmp_path / "none.mcap")))


def test_a_full_disk_stops_the_recording_not_the_link(tmp_path: Path) -> None:
    path = tmp_path / "full.jsonl"
    path.symlink_to("/dev/full")  # every write fails: No space left on device
    failures: list[str] = []
    recorder = Recorder(str(path), on_failure=failures.append)
    depths = []
    with rovlink.connect("sim://?seed=1", on_event=recorder.on_event) as rov:
        deadline = time.monotonic() + 10.0
        while not failures and time.monotonic() < deadline:
            depths.append(rov.depth_cm())
        depths.extend(rov.depth_cm() for _ in range(20))  # the link goes on after the failure
    recorder.close()
    assert failures
    assert "No space left on device" in failures[0]
    assert recorder.error == failures[0]
    assert str(path) in failures[0]
    assert len(depths) > 20


def test_an_unwritable_path_fails_at_once(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        Recorder(str(tmp_path / "no-such-directory" / "dive.mcap"))


def test_rotation_by_size_gives_files_that_each_read_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Rotation is looked at on each flush: every 50 ms, not each second, fills three files soon.
    monkeypatch.setattr("rovlink.recorder.recorder.FLUSH_INTERVAL_S", 0.05)
    path = str(tmp_path / "long.jsonl")
    recorder = Recorder(path, max_size_bytes=4096)
    with rovlink.connect("sim://?seed=1", on_event=recorder.on_event) as rov:
        deadline = time.monotonic() + 20.0
        while len(recorder.paths) < 3 and time.monotonic() < deadline:
            rov.sensors()
    recorder.close()
    assert recorder.paths[:3] == [rotated_path(path, index) for index in range(3)]
    total = 0
    for part in recorder.paths:
        entries = list(read_entries(part))
        assert entries[0].channel == "header"
        total += len(entries)
    assert total == recorder.entries_written


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl", ".csv"])
def test_any_cut_or_flipped_byte_gives_a_recording_error_or_entries(
    make_recording: MakeRecording, suffix: str, tmp_path: Path
) -> None:
    whole = Path(make_recording(f"dive{suffix}").path).read_bytes()
    damaged = tmp_path / f"damaged{suffix}"
    step = max(len(whole) // 150, 1)
    for offset in range(0, len(whole), step):
        for data in (
            whole[:offset],
            whole[:offset] + bytes([whole[offset] ^ 0x5A]) + whole[offset + 1 :],
        ):
            damaged.write_bytes(data)
            errors: list[RecordingError] = []
            try:
                for _ in read_entries(str(damaged)):
                    pass
            except RecordingError as error:
                errors.append(error)
            assert all(str(damaged) in str(error) for error in errors)


def test_a_failing_writer_stops_the_recording_not_the_link(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from rovlink.recorder import translate

    def broken(self: object, wall_ns: int, event: object) -> list[object]:
        raise RuntimeError("a bug in the writer")

    monkeypatch.setattr(translate.ClientEventLog, "entries", broken)
    failures: list[str] = []
    recorder = Recorder(str(tmp_path / "dive.jsonl"), on_failure=failures.append)
    with rovlink.connect("sim://?seed=1", on_event=recorder.on_event) as rov:
        deadline = time.monotonic() + 10.0
        while not failures and time.monotonic() < deadline:
            rov.depth_cm()
        depths = [rov.depth_cm() for _ in range(5)]  # the link goes on
    recorder.close()
    assert failures == [
        f"recording to {tmp_path / 'dive.jsonl'} stopped: the recorder failed (logged)"
    ]
    assert len(depths) == 5


def _csv_lines(make_recording: MakeRecording) -> list[bytes]:
    lines = Path(make_recording("dive.csv").path).read_bytes().splitlines(keepends=True)
    assert len(lines) >= 5  # the header and rows enough to damage one in the middle
    return lines


def test_a_csv_row_that_is_not_utf8_is_damage_after_the_rows_before_it(
    make_recording: MakeRecording, tmp_path: Path
) -> None:
    # Before, the file was decoded thousands of bytes at a time: one bad byte anywhere in the
    # first of them made the whole file "not UTF-8 text, so not a rovlink telemetry CSV".
    lines = _csv_lines(make_recording)
    lines[3] = lines[3][:4] + b"\xff" + lines[3][5:]
    damaged = tmp_path / "damaged.csv"
    damaged.write_bytes(b"".join(lines))
    entries, error = _read_all(str(damaged))
    assert len(entries) == 2
    assert error is not None
    assert str(error) == f"{damaged}: row 4 is damaged (not UTF-8 text); read 2 rows before it"
    assert not error.incomplete  # (status 1)


def test_a_csv_row_damaged_mid_file_is_damage_and_a_cut_last_row_is_not(
    make_recording: MakeRecording, tmp_path: Path
) -> None:
    # Before, any row that did not parse counted as a file cut short (status 0, no error).
    lines = _csv_lines(make_recording)
    damaged = tmp_path / "damaged.csv"
    damaged.write_bytes(b"".join([*lines[:3], lines[3].replace(b",", b";", 1), *lines[4:]]))
    entries, error = _read_all(str(damaged))
    assert len(entries) == 2
    assert error is not None
    assert str(error).startswith(f"{damaged}: row 4 is damaged (14 columns, not 15)")
    assert not error.incomplete
    cut = tmp_path / "cut.csv"
    cut.write_bytes(b"".join(lines)[: -len(lines[-1]) // 2])
    entries, error = _read_all(str(cut))
    assert len(entries) == len(lines) - 2
    assert error is not None
    assert f"row {len(lines)} is cut short" in str(error)
    assert error.incomplete  # (status 0)


@pytest.mark.parametrize("cut_bytes", [0, 1, 20], ids=lambda n: f"{n}-bytes")
def test_a_csv_cut_before_or_in_its_header_ends_early(
    make_recording: MakeRecording, tmp_path: Path, cut_bytes: int
) -> None:
    # A recorder killed in its first second leaves an empty .csv (its header is written with
    # the first second): it read as a foreign file, 'its header differs', where an .mcap or a
    # .jsonl reads as a recording that ends early with nothing in it.
    header = _csv_lines(make_recording)[0]
    cut = tmp_path / "killed.csv"
    cut.write_bytes(header[:cut_bytes])
    entries, damage = _read_all(str(cut))
    assert entries == []
    assert damage is not None
    assert damage.incomplete
    assert str(cut) in str(damage)
    assert damage.entries_read == 0


def test_a_csv_row_cut_in_its_last_value_is_cut_short_not_read(
    make_recording: MakeRecording, tmp_path: Path
) -> None:
    # A row cut in the middle of its last number parsed: 30 % power read as 3 %, and the
    # recording as whole.
    lines = _csv_lines(make_recording)[:-1]  # (and its closing row: cut before it)
    *columns, _, _ = lines[-1].rstrip(b"\n").split(b",")  # thrust_power_percent, event
    cut = tmp_path / "cut.csv"
    cut.write_bytes(b"".join([*lines[:-1], b",".join([*columns, b"3"])]))  # 30, cut
    entries, error = _read_all(str(cut))
    assert len(entries) == len(lines) - 2
    assert error is not None
    assert f"row {len(lines)} is cut short" in str(error)
    assert error.incomplete


@pytest.mark.parametrize("profile", ["ros2", ""])
def test_an_mcap_file_of_another_program_is_refused_by_name(tmp_path: Path, profile: str) -> None:
    # A ROS bag or a Foxglove recording read as a rovlink recording with nothing in it:
    # replay and decode printed nothing, with status 0.
    from mcap.writer import Writer

    path = tmp_path / "bag.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile=profile, library="another program")
        schema = writer.register_schema(name="Imu", encoding="jsonschema", data=b"{}")
        channel = writer.register_channel(topic="/imu", message_encoding="json", schema_id=schema)
        writer.add_message(channel_id=channel, log_time=1, publish_time=1, data=b'{"x": 1}')
        writer.finish()
    with pytest.raises(RecordingError) as caught:
        list(read_entries(str(path)))
    assert not isinstance(caught.value, RecordingDamagedError)
    assert str(caught.value).startswith(f"{path}: not a rovlink recording: an MCAP file")
    assert ("'ros2'" in str(caught.value)) is bool(profile)


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl"])
def test_a_recording_of_a_newer_format_version_is_refused_by_name(
    tmp_path: Path, suffix: str
) -> None:
    # It was read as if it were of this version: its fields may mean something else by then.
    path = str(tmp_path / f"newer{suffix}")
    sink = open_sink(path)
    sink.write(HeaderEntry(1.0, 1, "sim://", False, "crc8", "rovlink record", "9.0.0", 99))
    sink.write(WireEntry(1.5, 2, "out", b"#qd!"))
    sink.close()
    with pytest.raises(RecordingError) as caught:
        list(read_entries(path))
    assert not isinstance(caught.value, RecordingDamagedError)
    assert str(caught.value) == (
        f"{path}: recorded by rovlink record 9.0.0 in format version 99; rovlink "
        f"{rovlink.__version__} reads versions up to {FORMAT_VERSION}: upgrade rovlink to read it"
    )


@pytest.mark.parametrize("content", [b"hello\n", b"PK\x03\x04 a zip file, not a recording\n"])
def test_a_foreign_mcap_is_named_without_the_librarys_words(tmp_path: Path, content: bytes) -> None:
    # It said "not an MCAP recording (unpack requires a buffer of 8 bytes)".
    path = tmp_path / "notes.mcap"
    path.write_bytes(content)
    with pytest.raises(RecordingError) as caught:
        list(read_entries(str(path)))
    assert str(caught.value) == (
        f"{path}: not an MCAP recording (it does not start with MCAP's magic bytes: another "
        "kind of file named .mcap)"
    )


def _jsonl_of_a_short_session(path: str) -> JsonLinesSink:
    sink = JsonLinesSink(path)
    sink.write(HeaderEntry(1.0, 1, "sim://", False, "crc8", "rovlink send", "0.1.0"))
    sink.write(WireEntry(1.5, 2, "out", b"#qd!"))
    sink.flush()
    return sink


def test_a_jsonl_cut_between_two_lines_says_it_ends_early(tmp_path: Path) -> None:
    # A recorder killed just after a flush left whole lines: the file read as a whole recording,
    # and replay and plot said nothing of the cut.
    path = str(tmp_path / "killed.jsonl")
    _jsonl_of_a_short_session(path)._file.close()  # (killed: never closed by its recorder)
    entries, damage = _read_all(path)
    assert len(entries) == 2
    assert damage is not None
    assert damage.incomplete
    assert str(damage) == (
        f"{path}: the recording ends early, without its closing line (its recorder was stopped "
        "abruptly); read 2 entries"
    )


def test_a_closed_jsonl_reads_whole_without_its_closing_line(tmp_path: Path) -> None:
    path = str(tmp_path / "closed.jsonl")
    sink = _jsonl_of_a_short_session(path)
    sink.close()
    assert sink.held() == 2  # (the closing line is no line of the session)
    entries, damage = _read_all(path)
    assert damage is None
    assert [entry.channel for entry in entries] == ["header", "wire"]
    assert b'"event":"recording_end"' in Path(path).read_bytes().splitlines()[-1]


def test_a_jsonl_of_format_2_is_whole_without_a_closing_line(tmp_path: Path) -> None:
    path = tmp_path / "older.jsonl"
    header = HeaderEntry(1.0, 1, "sim://", False, "crc8", "rovlink send", "0.1.0", 2)
    path.write_text(json.dumps({"channel": "header", **header.to_json()}) + "\n")
    entries, damage = _read_all(str(path))
    assert (len(entries), damage) == (1, None)


def _csv_of_a_short_session(path: str) -> TelemetryCsvSink:
    sink = TelemetryCsvSink(path)
    values = dict.fromkeys(TELEMETRY_FIELDS)
    sink.write(TelemetryEntry(1.0, 1_000_000_000, {**values, "depth_cm": 12}))
    sink.write(TelemetryEntry(1.5, 1_500_000_000, {**values, "depth_cm": 14}))
    sink.write(WireEntry(2.5, 2_500_000_000, "in", b"$qd.14!"))  # (the session goes on)
    sink.flush()
    return sink


def test_a_csv_cut_between_two_rows_says_it_ends_early(tmp_path: Path) -> None:
    # A recorder killed just after a flush left whole rows: the file read as a whole recording,
    # and plot said nothing of the cut.
    path = str(tmp_path / "killed.csv")
    sink = _csv_of_a_short_session(path)
    sink._file.close()  # (killed: never closed by its recorder)
    entries, damage = _read_all(path)
    assert len(entries) == 2
    assert damage is not None
    assert damage.incomplete
    assert str(damage) == (
        f"{path}: the recording ends early, without its closing row (its recorder was stopped "
        "abruptly); read 2 rows"
    )


def test_a_closed_csv_reads_whole_and_ends_with_its_closing_row(tmp_path: Path) -> None:
    path = str(tmp_path / "closed.csv")
    sink = _csv_of_a_short_session(path)
    sink.close()
    assert sink.held() == 2  # (the closing row is no row of the session)
    entries, damage = _read_all(path)
    assert damage is None
    assert [entry.values["depth_cm"] for entry in entries if isinstance(entry, TelemetryEntry)] == [
        12,
        14,
    ]
    # When the session ended (its last entry), with the values held until then.
    closing = Path(path).read_text().splitlines()[-1].split(",")
    assert (closing[0], closing[2], closing[-1]) == ("2.500000", "14", "recording_end")


def test_a_csv_row_after_the_closing_row_is_damage(tmp_path: Path) -> None:
    path = tmp_path / "appended.csv"
    _csv_of_a_short_session(str(path)).close()
    rows = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join([*rows, rows[1]]))
    entries, damage = _read_all(str(path))
    assert len([entry for entry in entries if isinstance(entry, TelemetryEntry)]) == 2
    assert damage is not None
    assert not damage.incomplete
    assert "row 5 is damaged (a row after the closing row (recording_end))" in str(damage)


def test_a_csv_without_the_event_column_is_whole_without_a_closing_row(tmp_path: Path) -> None:
    # Written before the closing row: nothing in such a file can say that it was cut.
    path = tmp_path / "older.csv"
    empty = "," * (len(TELEMETRY_FIELDS) - 1)
    path.write_text(
        ",".join(UNENDED_HEADER) + "\n" + f"1.000000,1970-01-01T00:00:01.000000+00:00,12{empty}\n"
    )
    entries, damage = _read_all(str(path))
    assert damage is None
    assert [entry.values["depth_cm"] for entry in entries if isinstance(entry, TelemetryEntry)] == [
        12
    ]
