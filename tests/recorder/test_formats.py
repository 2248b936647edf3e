"""Record → read back through each format; the MCAP file as ``mcap``'s own reader sees it; the
CSV as pandas reads it."""

from __future__ import annotations

import json
import os
import re
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

import rovlink
from rovlink.protocol import COMMANDS, RESPONSES
from rovlink.recorder import (
    Entry,
    EventEntry,
    FrameEntry,
    HeaderEntry,
    Recorder,
    TelemetryEntry,
    WireEntry,
    format_of,
    read_entries,
)
from rovlink.recorder.entries import CHANNELS, TELEMETRY_FIELDS
from rovlink.recorder.telemetry import COMMAND_COLUMNS, RESPONSE_COLUMNS
from tests.recorder.conftest import MakeRecording, drive_a_short_dive


def _frames(entries: list[Entry]) -> list[tuple[str, str, str | None]]:
    return [
        (entry.direction, entry.name, entry.query)
        for entry in entries
        if isinstance(entry, FrameEntry)
    ]


def test_mcap_and_jsonl_hold_the_same_session(make_recording: MakeRecording) -> None:
    mcap_entries = list(read_entries(make_recording("dive.mcap").path))
    jsonl_entries = list(read_entries(make_recording("dive.jsonl").path))
    # Two runs of the same program: the same frames in the same order (the values may differ:
    # the simulator runs in real time).
    assert _frames(mcap_entries) == _frames(jsonl_entries)
    frames = _frames(mcap_entries)
    assert ("out", "start", None) in frames
    assert ("out", "th", None) in frames
    answers = [frame for frame in frames if frame[0] == "in"]
    assert answers
    assert all(frame[2] is not None for frame in answers)
    assert {frame[2] for frame in answers} >= {"qsa", "qd", "q.l"}


def test_a_recording_reads_back_exactly_as_written(make_recording: MakeRecording) -> None:
    recorder = make_recording("dive.jsonl")
    entries = list(read_entries(recorder.path))
    assert len(entries) == recorder.entries_written
    assert isinstance(entries[0], HeaderEntry)
    assert entries[0].url == "sim://?seed=1"
    # The wire holds every byte both ways, the readiness probe included.
    sent = b"".join(e.data for e in entries if isinstance(e, WireEntry) and e.direction == "out")
    received = b"".join(e.data for e in entries if isinstance(e, WireEntry) and e.direction == "in")
    assert sent.startswith(b"#crcoff!#qd!")
    assert b"#th.90.20!" in sent
    assert sent.endswith(b"#stop!")
    assert received.count(b"$qhe.") == 5
    times = [entry.t_s for entry in entries]
    assert times == sorted(times)
    # The wall clock of each entry is its monotonic time plus the clocks' offset.
    now_ns = time.time_ns()
    assert all(now_ns - 60e9 < entry.wall_ns <= now_ns for entry in entries)
    walls = [entry.wall_ns for entry in entries[1:]]
    assert walls == sorted(walls)
    locks = [e.detail for e in entries if isinstance(e, EventEntry) and e.event == "lock"]
    assert locks == ["unlocked", "locked"]
    rows = [e.values for e in entries if isinstance(e, TelemetryEntry)]
    assert 40 in [row["setpoint_cm"] for row in rows]
    last = rows[-1]
    assert last["setpoint_cm"] is None  # stop clears the depth target (P7)
    assert last["locked"] == 1
    assert last["leak"] == 0
    assert last["thrust_power_percent"] == 0  # stop: the thrust the controller applies


def test_mcap_is_valid_for_the_mcap_library(make_recording: MakeRecording) -> None:
    recorder = make_recording("dive.mcap")
    with open(recorder.path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        assert summary.statistics is not None
        topics = {channel.topic for channel in summary.channels.values()}
        assert topics == {f"/rovlink/{name}" for name in CHANNELS}
        schemas = {schema.name: json.loads(schema.data) for schema in summary.schemas.values()}
        assert {schema.encoding for schema in summary.schemas.values()} == {"jsonschema"}
        assert set(schemas["rovlink.Telemetry"]["properties"]) >= set(TELEMETRY_FIELDS)
        assert summary.statistics.message_count == recorder.entries_written
        assert summary.chunk_indexes  # chunked and indexed
        counted = sum(1 for _ in reader.iter_messages())
    assert counted == recorder.entries_written


def test_the_docs_name_every_topic_of_an_mcap_recording() -> None:
    # Regression: recording.md listed four topics; Foxglove shows five (/rovlink/header too).
    docs = Path(__file__).resolve().parents[2] / "docs" / "recording.md"
    row = next(
        line for line in docs.read_text("utf-8").splitlines() if line.startswith("| `.mcap`")
    )
    assert set(re.findall(r"`(/rovlink/\w+)`", row)) == {f"/rovlink/{name}" for name in CHANNELS}


def test_csv_is_the_telemetry_table_pandas_reads(make_recording: MakeRecording) -> None:
    pandas = pytest.importorskip("pandas", reason="pandas is in the test extra")
    recorder = make_recording("dive.csv")
    table = pandas.read_csv(recorder.path)
    assert list(table.columns) == ["t_s", "wall_time", *TELEMETRY_FIELDS, "event"]
    assert len(table) == 1 + sum(  # (the closing row)
        isinstance(entry, TelemetryEntry) for entry in read_entries(recorder.path)
    )
    assert table["event"].iloc[-1] == "recording_end"
    assert table["event"].iloc[:-1].isna().all()
    assert table["setpoint_cm"].dropna().iloc[-1] == 40
    assert table["t_s"].is_monotonic_increasing
    assert pandas.to_datetime(table["wall_time"]).notna().all()


def test_bin_is_the_raw_wire_that_decode_reads(
    make_recording: MakeRecording, tmp_path: Path
) -> None:
    bin_recorder = make_recording("dive.bin")
    raw = Path(bin_recorder.path).read_bytes()
    assert raw.startswith(b"#crcoff!#qd!")
    assert raw.endswith(b"#stop!")
    assert raw.count(b"$qd.") == 1 + 5 + 5  # the probe, five qsa, five qd


def test_unknown_suffix_is_refused_with_the_known_ones() -> None:
    with pytest.raises(ValueError, match=r"dive\.txt: unknown recording format '\.txt'"):
        format_of("dive.txt")


def test_a_name_without_a_suffix_is_refused_as_such() -> None:
    # It said "unknown recording format ''".
    with pytest.raises(ValueError, match="no suffix") as caught:
        format_of("dives/dive")
    assert str(caught.value) == (
        "dives/dive: no suffix to choose the recording format by; use .mcap, .jsonl, .csv or .bin"
    )


def test_telemetry_columns_come_from_the_command_table() -> None:
    responses = {spec.name: spec for spec in RESPONSES}
    commands = {spec.name: spec for spec in COMMANDS}
    for name, columns in RESPONSE_COLUMNS.items():
        assert len(columns) == len(responses[name].arguments)
    for name, columns in COMMAND_COLUMNS.items():
        assert len(columns) == len(commands[name].arguments)
    used = {c for cs in (*RESPONSE_COLUMNS.values(), *COMMAND_COLUMNS.values()) for c in cs}
    assert used | {"locked"} == set(TELEMETRY_FIELDS)


def _closing(entry: Entry) -> bool:
    """A ``.csv``'s closing row, read as when the recording ended (no row of the session)."""
    return isinstance(entry, EventEntry) and entry.event == "recording_end"


@pytest.mark.parametrize("suffix", [".mcap", ".jsonl", ".csv"])
def test_a_recording_into_a_pipe_holds_the_whole_session(tmp_path: Path, suffix: str) -> None:
    # A pipe to another program (a FIFO) refuses fsync: the recording stopped at its first
    # flush ("recording to live.jsonl stopped: Invalid argument").
    fifo = tmp_path / f"live{suffix}"
    os.mkfifo(fifo)
    copy = tmp_path / f"copy{suffix}"
    reader = threading.Thread(target=lambda: copy.write_bytes(fifo.read_bytes()))
    reader.start()
    recorder = Recorder(str(fifo), url="sim://?seed=1")  # (opens once the reader has)
    with recorder, rovlink.connect("sim://?seed=1", on_event=recorder.on_event) as rov:
        drive_a_short_dive(rov)
        assert recorder.sync() is None
    reader.join(timeout=10)
    assert recorder.error is None
    entries = [entry for entry in read_entries(str(copy)) if not _closing(entry)]
    assert len(entries) == recorder.held() > 1  # (.csv: the telemetry rows)
    assert any(isinstance(entry, TelemetryEntry) for entry in entries)
