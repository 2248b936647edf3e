"""``rovlink record`` as a tap between a program and a controller, ``--record`` on a driving
command, ``rovlink replay`` (printing, and resending to a controller), ``rovlink plot`` and
``rovlink decode`` of a recording."""

from __future__ import annotations

import io
import json
import os
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import rovlink
from rovlink.cli import main
from rovlink.cli.recording import recorded_nothing
from rovlink.client import Client
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.protocol import Command, Response, encode
from rovlink.recorder import (
    Entry,
    EventEntry,
    FrameEntry,
    HeaderEntry,
    Recorder,
    TelemetryEntry,
    WireEntry,
    read_entries,
)
from rovlink.recorder.entries import FORMAT_VERSION, TELEMETRY_FIELDS
from rovlink.recorder.formats import open_sink
from tests.cli.conftest import RunCli
from tests.client.fake_controller import FakeControllerServer
from tests.client.sim_process import running_sim

_SRC = str(Path(__file__).resolve().parents[2] / "src")


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _start_recording(url: str, output: Path, tap: str) -> subprocess.Popen[str]:
    """``rovlink record URL -o OUTPUT --tap TAP`` as a process; its stderr is a pipe."""
    return subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from rovlink.cli import main; main()",
            "record",
            url,
            "-o",
            str(output),
            "--tap",
            tap,
        ],
        env={**os.environ, "PYTHONPATH": _SRC},
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.integration
def test_record_taps_a_program_and_a_controller(tmp_path: Path) -> None:
    output = tmp_path / "tapped.mcap"
    tap_port = _free_port()
    with running_sim("--tcp", "127.0.0.1:0", "--seed", "1", "--watchdog", "0") as sim:
        assert sim.tcp_url is not None
        recorder = _start_recording(sim.tcp_url, output, f"socket://127.0.0.1:{tap_port}")
        try:
            # Its first line says it is ready (a probe's connection would be the tap's one
            # program until the tap saw it leave, and the next one told it is busy).
            assert recorder.stderr is not None
            assert f"program's side: socket://127.0.0.1:{tap_port}" in recorder.stderr.readline()
            with rovlink.connect(f"socket://127.0.0.1:{tap_port}") as rov:
                rov.start()
                rov.hold_depth(30)
                readings = [rov.sensors() for _ in range(3)]
                rov.stop()
        finally:
            recorder.send_signal(signal.SIGTERM)
            _, err = recorder.communicate(timeout=20)
    assert recorder.returncode == 0, err
    assert "recorded" in err
    frames = [entry for entry in read_entries(str(output)) if isinstance(entry, FrameEntry)]
    sent = [frame.name for frame in frames if frame.direction == "out"]
    assert sent[-5:] == ["qsa", "qsa", "qsa", "stop"][-4:] or "stop" in sent
    assert {"start", "mvd", "qsa", "stop"} <= set(sent)
    answers = [frame for frame in frames if frame.direction == "in" and frame.query == "qsa"]
    assert len(answers) >= 18  # six replies to each qsa, matched by the tap itself
    recorded_depths = [frame.values[0] for frame in answers if frame.name == "qd"][-3:]
    assert recorded_depths == [reading.depth_cm for reading in readings]


def test_record_option_on_send_records_the_session(run_cli: RunCli, tmp_path: Path) -> None:
    output = tmp_path / "send.jsonl"
    result = run_cli("send", "sim://?seed=2", "--record", str(output), "start", "qd", "stop")
    assert result.status == 0, result.err
    assert f"to {output}" in result.err
    names = [(e.direction, e.name) for e in read_entries(str(output)) if isinstance(e, FrameEntry)]
    assert ("out", "start") in names
    assert ("in", "qd") in names
    assert names[-1] == ("out", "stop")


@pytest.mark.parametrize(
    ("options", "named"),
    [
        (("--max-size", "100M"), "--max-size needs"),
        (("--split", "10m"), "--split needs"),
        (("--overwrite",), "--overwrite needs"),
        (("--overwrite", "--split", "1h"), "--overwrite, --split need"),
    ],
)
def test_recording_options_without_record_are_refused(
    run_cli: RunCli, options: tuple[str, ...], named: str
) -> None:
    # Taken silently, they would leave a team believing the dive was being recorded.
    result = run_cli("send", "sim://", *options, "qd")
    assert result.status == 2
    assert f"{named} --record FILE" in result.err
    assert result.out == ""  # refused before anything was sent


def test_record_option_refuses_an_unknown_format(run_cli: RunCli, tmp_path: Path) -> None:
    result = run_cli("send", "sim://", "--record", str(tmp_path / "x.txt"), "qd")
    assert result.status == 2
    assert "unknown recording format '.txt'" in result.err


@pytest.mark.parametrize("name", ["dive.txt", "dive"])
@pytest.mark.parametrize(
    "command",
    [
        ("send", "sim://", "qd", "--record"),
        ("record", "sim://", "--duration", "0.1", "-o"),
        ("replay",),
        ("plot", "-o", "dive.png"),
    ],
    ids=lambda command: command[0],
)
@pytest.mark.parametrize("exists", [False, True], ids=["new", "existing"])
def test_a_recording_name_of_no_format_is_a_usage_error_in_every_command(
    run_cli: RunCli,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    command: tuple[str, ...],
    name: str,
    exists: bool,
) -> None:
    # plot said it with status 1, and record said of an existing file that it exists already
    # (status 1), where send, replay and record said a usage error (status 2).
    monkeypatch.chdir(tmp_path)
    if exists:
        Path(name).write_text("x\n")
    result = run_cli(*command, name)
    assert result.status == 2, result.err
    assert result.err.startswith(f"usage: rovlink {command[0]} ")
    assert result.err.splitlines()[-1].startswith(f"rovlink {command[0]}: error: {name}: ")
    assert "recording format" in result.err
    assert not Path("dive.png").exists()


@pytest.mark.parametrize("name", ["dive.csv", "dive.bin"])
def test_replay_of_a_missing_file_says_it_is_missing(
    run_cli: RunCli, tmp_path: Path, name: str
) -> None:
    # Before, a missing .csv was said to hold only the telemetry table (and a .bin to be
    # wire bytes): a mistyped name sent the user to plot a file that is not there.
    path = tmp_path / name
    result = run_cli("replay", str(path))
    assert result.status == 1
    assert result.err.strip().splitlines()[-1] == (
        f"rovlink replay: {path}: No such file or directory"
    )


def _record(path: Path, url: str = "sim://?seed=4") -> None:
    recorder = Recorder(str(path), url=url)
    with recorder, rovlink.connect(url, on_event=recorder.on_event) as rov:
        rov.start()
        rov.hold_depth(30)
        for _ in range(8):
            rov.sensors()
            time.sleep(0.05)
        rov.stop()


def test_replay_prints_the_session(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "dive.mcap"
    _record(path)
    result = run_cli("replay", str(path))
    assert result.status == 0, result.err
    lines = result.out.splitlines()
    assert "rovlink" in lines[0]
    assert "sim://?seed=4" in lines[0]
    assert any(line.endswith("out  #mvd.30!") for line in lines)
    assert any("$qd." in line and "(answers qsa, " in line for line in lines)
    assert any("lock start: unlocked" in line for line in lines)
    wire = run_cli("replay", str(path), "--wire").out
    assert ">>   b'#crcoff!#qd!'" in wire


def test_replay_into_the_same_simulator_reproduces_the_replies(
    run_cli: RunCli, tmp_path: Path
) -> None:
    path = tmp_path / "dive.mcap"
    _record(path)
    # A real-time simulator: a command may land one control tick earlier or later than it
    # did, which moves a value by a unit or two while the robot moves.
    result = run_cli("replay", str(path), "--to", "sim://?seed=4", "--tolerance", "3")
    assert result.status == 0, result.out
    assert "8 queries compared: 8 as recorded, 0 different" in result.out


def _commands_sent_on_connect(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The names of the commands the next clients of ``rovlink.connect`` send (their sessions'
    own keep-alives and fences left out), as they are sent."""
    sent: list[str] = []
    connect = rovlink.connect

    def note(event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and event.command and not event.by_session:
            sent.append(event.command.name)

    def connect_noting(url: str, **options: Any) -> Client:
        return connect(url, on_event=note, **options)

    monkeypatch.setattr(rovlink, "connect", connect_noting)
    return sent


def _cut_before_the_stop_on_close(path: Path) -> None:
    """Leave the recording at ``path`` as a killed recorder or a ``--split`` part leaves it:
    without the ``#stop!`` the driver sent as the link closed (nor anything after)."""
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    cut = next(
        index
        for index, line in enumerate(lines)
        if '"name":"stop"' in line and '"by_session":true' in line
    )
    path.write_text("".join(lines[:cut]), encoding="utf-8")


def test_replay_of_a_program_that_closed_while_moving_ends_with_the_recorded_stop(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "dive.jsonl"
    assert run_cli("send", "sim://?seed=1", "--record", str(path), "start", "th 0 50").status == 0
    sent = _commands_sent_on_connect(monkeypatch)
    result = run_cli("replay", str(path), "--to", "sim://?seed=1")
    assert result.status == 0, result.err
    assert sent[-3:] == ["start", "th", "stop"]  # the driver's stop on close, as recorded
    assert "rovlink replay: sent #stop!" not in result.err


@pytest.mark.parametrize(
    ("recorded", "stopped"),
    [
        (["start", "th 0 50", "qd"], True),  # cut mid-dive: a --split part, a killed recorder
        (["th 0 50", "qd"], True),  # motion with the lock as the controller had it
        (["start", "th 0 50", "qd", "stop"], False),  # it stopped the robot itself
        (["qd"], False),  # queries move nothing
    ],
    ids=["unlocked", "lock-unknown", "ended-with-stop", "queries-only"],
)
def test_replay_to_a_controller_never_leaves_the_robot_moving(
    run_cli: RunCli,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    recorded: list[str],
    stopped: bool,
) -> None:
    path = tmp_path / "dive.jsonl"
    assert run_cli("send", "sim://?seed=1", "--record", str(path), *recorded).status == 0
    if stopped:
        _cut_before_the_stop_on_close(path)
    sent = _commands_sent_on_connect(monkeypatch)
    result = run_cli("replay", str(path), "--to", "sim://?seed=1")
    assert result.status == 0, result.err
    replayed = [text.split()[0] for text in recorded]
    if stopped:
        assert sent[-len(recorded) - 1 :] == [*replayed, "stop"]
        assert "rovlink replay: sent #stop!" in result.err
    else:
        assert sent[-len(recorded) :] == replayed
        assert "#stop!" not in result.err


class _ClosedOutput(io.StringIO):
    """Standard output whose reader has gone (``rovlink replay … | head -1`` after one line)."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


def test_replay_to_a_controller_ends_with_stop_when_its_output_fails(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "dive.jsonl"
    recorded = run_cli("send", "sim://?seed=1&leak_at=0", "--record", str(path), "start", "q.l")
    assert recorded.status == 0
    sent = _commands_sent_on_connect(monkeypatch)
    monkeypatch.setattr(sys, "stdout", _ClosedOutput())
    # No leak now: the difference is printed, and the printing fails.
    result = run_cli("replay", str(path), "--to", "sim://?seed=1")
    assert result.status == 0  # as any filter whose reader stopped early
    assert sent[-3:] == ["start", "q.l", "stop"]
    assert "rovlink replay: sent #stop!" in result.err


def test_replay_into_a_changed_controller_shows_what_changed(
    run_cli: RunCli, tmp_path: Path
) -> None:
    path = tmp_path / "dive.mcap"
    _record(path)
    result = run_cli("replay", str(path), "--to", "sim://?seed=4&leak_at=0", "--tolerance", "3")
    assert result.status == 1
    assert "qsa: recorded $q.l.0!, now $q.l.1!" in result.out
    assert "different" in result.out


def test_replay_to_times_a_difference_as_the_session_is_listed(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # A difference was timed from the first command replayed, the listing from the recording's
    # start: the query listed at 2.000 s was reported at 0.500 s.
    path = tmp_path / "dive.jsonl"
    _write(
        path,
        HeaderEntry(1.0, 1, "sim://?seed=1", False, "crc8", "test", "0"),
        FrameEntry(2.5, 2, "out", "command", "qr", ()),
        FrameEntry(3.0, 3, "out", "command", "qd", ()),
        FrameEntry(3.001, 3, "in", "response", "qd", (9999,), query="qd", round_trip_ms=1.0),
    )
    listed = run_cli("replay", str(path))
    assert "    2.000 s  out  #qd!" in listed.out
    result = run_cli("replay", str(path), "--to", "sim://?seed=1", "--speed", "100")
    assert result.status == 1, result.err
    assert result.out.startswith("    2.000 s  qd: recorded $qd.9999!, now $qd.")


def test_replay_to_holds_no_more_of_a_recording_than_its_commands(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Every entry was held while the commands were resent: 250 MB for an hour of 10 Hz qsa.
    most_alive = 0

    def entries(path: str) -> Iterator[Entry]:
        nonlocal most_alive
        yield HeaderEntry(1.0, 1, "sim://?seed=1", False, "crc8", "test", "0")
        for index in range(2000):
            _CountedWire.alive += 1
            most_alive = max(most_alive, _CountedWire.alive)
            yield _CountedWire(1.0 + index / 1000, 1, "in", b"$qd.10!")
        yield FrameEntry(3.0, 3, "out", "command", "qd", ())

    monkeypatch.setattr("rovlink.recorder.read_entries", entries)
    result = run_cli("replay", str(tmp_path / "dive.jsonl"), "--to", "sim://?seed=1")
    assert "1 commands replayed" in result.out, result.err
    assert most_alive < 10


def test_replay_to_in_checksum_mode_stays_in_it(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The recording driver's own #crcoff! on connecting was recorded as the program's: the
    # replay resent it, and went on without checksums though --checksum asked for them.
    path = tmp_path / "plain.jsonl"
    assert run_cli("send", "sim://?seed=1", "--record", str(path), "qd").status == 0
    [mode_frame] = [
        e for e in read_entries(str(path)) if isinstance(e, FrameEntry) and e.name == "crcoff"
    ]
    assert mode_frame.by_session
    out, written = _replay(run_cli, path, monkeypatch, "--checksum")
    assert out.startswith("1 commands replayed")
    # (The readiness probe's own #crcoff! comes before the #crcon! of --checksum.)
    in_checksum_mode = written.partition(b"#crcon!")[2]
    assert in_checksum_mode.startswith(b"#qd8C!")
    assert b"#crcoff!" not in in_checksum_mode


def _replay(
    run_cli: RunCli, path: Path, monkeypatch: pytest.MonkeyPatch, *options: str
) -> tuple[str, bytes]:
    """``rovlink replay PATH --to sim://…``: what it printed, and what it wrote to the
    controller."""
    written: list[bytes] = []
    connect = rovlink.connect

    def connect_noting(url: str, **settings: Any) -> Client:
        def note(event: ClientEvent) -> None:
            if isinstance(event, BytesSent):
                written.append(event.data)

        return connect(url, on_event=note, **settings)

    monkeypatch.setattr(rovlink, "connect", connect_noting)
    result = run_cli("replay", str(path), "--to", "sim://?seed=1", *options)
    assert result.status == 0, result.err
    return result.out, b"".join(written)


def test_a_recording_made_with_checksum_says_it_starts_plain(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Its header said checksum on, though the driver's connect probe and mode frame went plain.
    path = tmp_path / "checked.jsonl"
    assert run_cli("send", "sim://?seed=1", "--checksum", "--record", str(path), "qd").status == 0
    entries = list(read_entries(str(path)))
    header = entries[0]
    assert isinstance(header, HeaderEntry)
    assert (header.checksum, header.format_version) == (False, FORMAT_VERSION)
    [first_out] = [e for e in entries if isinstance(e, WireEntry) and e.direction == "out"][:1]
    assert first_out.data.startswith(b"#crcoff!#qd!")  # (the connect probe: plain)
    # The mode frame, and the event of the change, say when checksums start.
    frames = [(e.name, e.by_session) for e in entries if isinstance(e, FrameEntry)]
    assert frames[0] == ("crcon", True)
    changes = [(e.name, e.detail) for e in entries if isinstance(e, EventEntry)]
    assert ("checksum", "on") in changes
    decoded = run_cli("decode", str(path), "--stats")
    assert list(json.loads(decoded.out)["events"]) == ["frame"]  # (no error: each in its mode)
    listed = run_cli("replay", str(path)).out.splitlines()
    assert "(no checksum)" in listed[0]
    assert "mode changed checksum: on" in "\n".join(listed)
    # Replayed in the mode the recorded driver asked for, as before.
    replayed = _replay(run_cli, path, monkeypatch)[1].partition(b"#crcon!")[2]
    assert replayed.startswith(b"#qd8C!")


def test_replay_of_a_format_1_recording_made_with_checksum_stays_in_checksum_mode(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "older.jsonl"
    _write(
        path,
        HeaderEntry(1.0, 1, "sim://", True, "crc8", "rovlink send", "0.1.0", format_version=1),
        WireEntry(1.1, 1, "out", b"#crcoff!#qd!", by_session=True),
        WireEntry(1.2, 1, "in", b"$qd.0!"),
        FrameEntry(1.3, 1, "out", "command", "crcon", (), by_session=True),
        FrameEntry(1.4, 1, "out", "command", "qd", ()),
        FrameEntry(1.5, 1, "in", "response", "qd", (0,), query="qd"),
    )
    replayed = _replay(run_cli, path, monkeypatch)[1].partition(b"#crcon!")[2]
    assert replayed.startswith(b"#qd8C!")


def test_replay_reports_damage_after_what_it_read(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "dive.jsonl"
    _record(path)
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join(lines[:20]) + b"not json\n" + b"".join(lines[20:]))
    result = run_cli("replay", str(path))
    assert result.status == 1
    assert len(result.out.splitlines()) > 5
    assert f"{path}: line 21 is damaged" in result.err


def _write(path: Path, *entries: Entry) -> None:
    sink = open_sink(str(path))
    for entry in entries:
        sink.write(entry)
    sink.close()


@pytest.mark.parametrize("to", [(), ("--to", "sim://?seed=1")], ids=["printed", "resent"])
@pytest.mark.parametrize(
    "frame",
    [
        FrameEntry(2.0, 2, "out", "command", "nosuch", ()),
        FrameEntry(2.0, 2, "out", "command", "th", (999, 5)),
        FrameEntry(2.0, 2, "out", "command", "th", ()),
        FrameEntry(2.0, 2, "in", "response", "zz", (), query="qd"),
    ],
    ids=["unknown-command", "out-of-range", "too-few-values", "unknown-response"],
)
def test_replay_of_a_frame_the_protocol_refuses_names_the_damage(
    run_cli: RunCli, tmp_path: Path, to: tuple[str, ...], frame: FrameEntry
) -> None:
    path = tmp_path / "damaged.jsonl"
    _write(path, HeaderEntry(1.0, 1, "sim://?seed=1", False, "crc8", "test", "0"), frame)
    result = run_cli("replay", str(path), *to)
    assert result.status == 1
    assert f"{path}: line 2 is damaged (frame entry: " in result.err
    assert len(result.err.splitlines()) == 1


@pytest.mark.parametrize(
    "entry",
    [
        FrameEntry(2.0, 2, "in", "response", "qd", (5,), query="qd", round_trip_ms="x"),  # type: ignore[arg-type]
        EventEntry(2.0, 2, 5, "start"),  # type: ignore[arg-type]
    ],
    ids=["round-trip", "event"],
)
def test_replay_of_a_value_of_another_type_names_the_damage(
    run_cli: RunCli, tmp_path: Path, entry: Entry
) -> None:
    path = tmp_path / "mistyped.jsonl"
    _write(path, HeaderEntry(1.0, 1, "sim://?seed=1", False, "crc8", "test", "0"), entry)
    result = run_cli("replay", str(path))
    assert result.status == 1
    assert f"{path}: line 2 is damaged ({entry.channel} entry: " in result.err


@pytest.mark.parametrize(
    ("suffix", "depth_cm", "shown"),
    [
        (".jsonl", 10**400, "10000000… (401 digits)"),
        (".csv", 10**400, "10000000… (401 digits)"),
        (".mcap", 10_000, "10000"),
    ],
    ids=["jsonl", "csv", "mcap"],
)
def test_plot_of_a_telemetry_value_out_of_its_range_names_the_damage(
    run_cli: RunCli, tmp_path: Path, suffix: str, depth_cm: int, shown: str
) -> None:
    # Before, no controller's value and no recorder's: plotted as a spike, and past a float's
    # range a traceback (OverflowError).
    values: dict[str, int | None] = dict.fromkeys(TELEMETRY_FIELDS)
    good = TelemetryEntry(2.0, 2_000_000_000, {**values, "depth_cm": 30})
    bad = TelemetryEntry(3.0, 3_000_000_000, {**values, "depth_cm": depth_cm})
    path = tmp_path / f"damaged{suffix}"
    _write(path, HeaderEntry(1.0, 1, "sim://?seed=1", False, "crc8", "test", "0"), good, bad)
    result = run_cli("plot", str(path), "-o", str(tmp_path / "dive.png"))
    assert result.status == 1
    assert f"(telemetry depth_cm must be in 0–9999, got {shown})" in result.err
    assert result.err.startswith(f"plotted {path}")  # the good row, before the damage
    assert (tmp_path / "dive.png").exists()


def test_replay_of_a_header_with_an_unknown_algorithm_names_the_file(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # Before, a usage error that blamed --to: "rovlink replay: error: --to: algorithm must be
    # one of crc8, xor, sum8, got 'nope'" (status 2), of a damaged header.
    path = tmp_path / "damaged.jsonl"
    header = HeaderEntry(1.0, 1, "sim://?seed=1", True, "nope", "test", "0")
    _write(path, header, FrameEntry(2.0, 2, "out", "command", "qd", ()))
    result = run_cli("replay", str(path), "--to", "sim://")
    assert result.status == 1
    assert result.err == (
        f"rovlink replay: {path}: the header's unknown checksum algorithm 'nope'; expected one "
        "of: crc8, sum8, xor\n"
    )


def test_replay_of_a_foreign_file_is_one_clear_line(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "photo.mcap"
    path.write_bytes(b"\x89PNG\r\n\x1a\n not a recording")
    result = run_cli("replay", str(path))
    assert result.status == 1
    assert (
        result.err.strip()
        == f"rovlink replay: {path}: not an MCAP recording ("
        + (result.err.strip().split("not an MCAP recording (", 1)[1])
    )


def test_plot_writes_a_png_of_the_expected_size(run_cli: RunCli, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")
    path = tmp_path / "dive.mcap"
    _record(path)
    image = tmp_path / "dive.png"
    result = run_cli("plot", str(path), "-o", str(image))
    assert result.status == 0, result.err
    header = image.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", header[16:24])
    assert (width, height) == (1200, 1100)


def test_plot_show_without_a_display_writes_nothing_and_says_what_would(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, the error told to "use -o IMAGE", given already.
    path = tmp_path / "dive.mcap"
    _record(path)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    image = tmp_path / "dive.png"
    result = run_cli("plot", str(path), "-o", str(image), "--show")
    assert (result.status, result.err) == (
        1,
        f"rovlink plot: --show needs a display (none here); without --show the plot is "
        f"written to {image} alone\n",
    )
    assert not image.exists()


@pytest.mark.integration
def test_plot_show_where_no_window_can_open_is_an_error(tmp_path: Path) -> None:
    # A display that cannot be opened (here, none at that number; elsewhere, no toolkit such as
    # tkinter): matplotlib draws without a window. Before, the command ended with status 0, a
    # UserWarning ("FigureCanvasAgg is non-interactive") and no window.
    pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")
    path = tmp_path / "dive.mcap"
    _record(path)
    environment = {
        name: value
        for name, value in os.environ.items()
        if name not in ("MPLBACKEND", "WAYLAND_DISPLAY")
    }
    environment["DISPLAY"] = ":9999"
    result = subprocess.run(
        [sys.executable, "-m", "rovlink", "plot", str(path), "--show"],
        env=environment,
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert (result.returncode, result.stderr) == (
        1,
        "rovlink plot: --show cannot open a window on display :9999 (no display there, or no "
        "window toolkit for matplotlib: tkinter, Qt or GTK); use -o IMAGE\n",
    )


def test_plot_of_a_file_whose_name_is_not_utf8(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A name with a Latin-1 byte ended in a traceback of the PNG renderer (its title).
    pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")
    values: dict[str, int | None] = dict.fromkeys(TELEMETRY_FIELDS)
    path = tmp_path / os.fsdecode(b"plong\xe9e.jsonl")
    _write(path, TelemetryEntry(2.0, 2_000_000_000, {**values, "depth_cm": 30}))
    image = tmp_path / "dive.png"
    stderr = io.StringIO()  # (the real one writes such a name with a backslash escape)
    monkeypatch.setattr(sys, "stderr", stderr)
    assert main(["plot", str(path), "-o", str(image)]) == 0, stderr.getvalue()
    assert image.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


class _CountedWire(WireEntry):
    """A wire entry that counts how many of its kind are alive."""

    alive = 0

    def __del__(self) -> None:
        _CountedWire.alive -= 1


def test_plot_holds_no_more_of_a_recording_than_its_telemetry(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Every entry was held until the plot was drawn: an hour of 10 Hz qsa took 290 MB, most
    # of it wire and frames that a plot never draws.
    pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")
    values: dict[str, int | None] = dict.fromkeys(TELEMETRY_FIELDS)
    most_alive = 0

    def entries(path: str) -> Iterator[Entry]:
        nonlocal most_alive
        yield TelemetryEntry(1.0, 1, {**values, "depth_cm": 10})
        for index in range(2000):
            _CountedWire.alive += 1
            most_alive = max(most_alive, _CountedWire.alive)
            yield _CountedWire(1.0 + index / 1000, 1, "in", b"$qd.10!")
        yield TelemetryEntry(3.0, 3, {**values, "depth_cm": 20})

    monkeypatch.setattr("rovlink.recorder.read_entries", entries)
    result = run_cli("plot", str(tmp_path / "dive.jsonl"), "-o", str(tmp_path / "dive.png"))
    assert result.status == 0, result.err
    assert most_alive < 10


def test_plot_of_a_raw_capture_says_there_is_no_telemetry(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "wire.bin"
    path.write_bytes(b"#qd!$qd.1!")
    result = run_cli("plot", str(path), "-o", str(tmp_path / "x.png"))
    assert result.status == 1
    assert "has no telemetry to plot" in result.err


def test_plot_of_a_recording_damaged_before_its_telemetry_names_the_damage(
    run_cli: RunCli, tmp_path: Path
) -> None:
    pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")
    path = tmp_path / "dive.jsonl"
    _write(path, HeaderEntry(1.0, 1, "sim://?seed=1", False, "crc8", "test", "0"))
    with path.open("ab") as damaged:  # (after the line that ends a closed file)
        damaged.write(b'{"channel":"telemetry","t_s":"x","wall_ns":1}\n')
    image = tmp_path / "x.png"
    result = run_cli("plot", str(path), "-o", str(image))
    assert result.status == 1
    assert result.err == (
        f"rovlink plot: {path}: line 3 is damaged (telemetry entry: t_s must be a number, "
        "got 'x'); read 1 entries before it; no telemetry before it to plot\n"
    )
    assert not image.exists()


def test_decode_reads_a_recordings_wire(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "dive.mcap"
    _record(path)
    result = run_cli("decode", str(path), "--stats")
    assert result.status == 0, result.err
    assert '"qsa": 8' in result.out


def test_decode_of_a_telemetry_csv_points_to_plot(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "dive.csv"
    _record(path)
    result = run_cli("decode", str(path))
    assert result.status == 1
    assert result.out == ""
    assert f"{path} holds only the telemetry table, not the wire: rovlink plot {path}" in (
        result.err
    )


def test_decode_of_a_capture_named_csv_decodes_it(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "capture.csv"
    path.write_bytes(b"#qd!$qd.1!")
    result = run_cli("decode", str(path), "--stats")
    assert result.status == 0, result.err
    assert '"frame": 2' in result.out


@pytest.mark.integration
def test_record_taps_a_program_through_a_pseudo_terminal(tmp_path: Path) -> None:
    output = tmp_path / "tapped.jsonl"
    with running_sim("--tcp", "127.0.0.1:0", "--seed", "1", "--watchdog", "0") as sim:
        assert sim.tcp_url is not None
        recorder = _start_recording(sim.tcp_url, output, "pty")
        try:
            assert recorder.stderr is not None
            first_line = recorder.stderr.readline()
            found = re.search(r"program's side: (\S+);", first_line)
            assert found, first_line
            with rovlink.connect(found.group(1)) as rov:
                depths = [rov.depth_cm() for _ in range(3)]
                rov.claw_open()
        finally:
            recorder.send_signal(signal.SIGTERM)
            _, err = recorder.communicate(timeout=20)
    assert recorder.returncode == 0, err
    entries = list(read_entries(str(output)))
    frames = [entry for entry in entries if isinstance(entry, FrameEntry)]
    replies = [frame.values[0] for frame in frames if frame.query == "qd"]
    assert replies[-3:] == depths
    assert ("out", "h+") in [(frame.direction, frame.name) for frame in frames]


async def test_record_option_on_an_asyncio_tool(tmp_path: Path) -> None:
    """The console and the monitor connect through ``connect_async``: --record records them."""
    from rovlink.cli import build_parser, link_options

    output = tmp_path / "console.mcap"
    args = build_parser("console").parse_args(["console", "sim://?seed=5", "--record", str(output)])
    args.on_exit = []
    connect = link_options.connect_async(args)
    client = await connect(lambda event: None)
    try:
        await client.depth_cm()
        await client.start()
    finally:
        await client.close()
    for finish in args.on_exit:
        finish()
    frames = [e for e in read_entries(str(output)) if isinstance(e, FrameEntry)]
    assert [(f.direction, f.name) for f in frames if not f.by_session][-3:] == [
        ("out", "qd"),
        ("in", "qd"),
        ("out", "start"),
    ]


def test_replay_follows_the_recorded_pace(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "dive.jsonl"
    _record(path)  # about 0.4 s of queries
    started = time.monotonic()
    fast = run_cli("replay", str(path), "--speed", "1000")
    fast_s = time.monotonic() - started
    started = time.monotonic()
    paced = run_cli("replay", str(path), "--follow")
    paced_s = time.monotonic() - started
    assert fast.out == paced.out
    entries = list(read_entries(str(path)))
    span_s = entries[-1].t_s - entries[1].t_s
    assert paced_s >= span_s * 0.9  # it waited for the recorded times
    assert fast_s < paced_s


@pytest.mark.parametrize(
    ("typed", "minimum"),
    [("4k", "4096 bytes (4.096k)"), ("4000", "4096 bytes"), ("0.001M", "4096 bytes (0.004096M)")],
)
def test_a_max_size_too_small_states_the_minimum_exactly(
    run_cli: RunCli, tmp_path: Path, typed: str, minimum: str
) -> None:
    result = run_cli("demo", "sim://", "--record", str(tmp_path / "ms.mcap"), "--max-size", typed)
    assert result.status == 2
    assert f"{typed!r} is too small for a recording file: at least {minimum}" in result.err
    assert not (tmp_path / "ms.mcap").exists()


def _held_in(path: Path) -> int:
    """What ``path`` holds, counted as its format counts: messages, lines, rows, bytes."""
    if path.suffix == ".bin":
        return len(path.read_bytes())
    # (A .csv's closing row, read as when the recording ended, is no row of the session.)
    closing = [EventEntry] if path.suffix == ".csv" else []
    return len([entry for entry in read_entries(str(path)) if type(entry) not in closing])


@pytest.mark.parametrize(
    ("suffix", "unit"),
    [(".mcap", "messages"), (".jsonl", "lines"), (".csv", "rows"), (".bin", "bytes")],
)
def test_the_summary_counts_what_the_file_holds_in_its_own_terms(
    run_cli: RunCli, tmp_path: Path, suffix: str, unit: str
) -> None:
    path = tmp_path / f"send{suffix}"
    result = run_cli("send", "sim://?seed=2", "--record", str(path), "start", "qsa", "qd", "stop")
    assert result.status == 0, result.err
    assert f"recorded {_held_in(path)} {unit} in " in result.err


#: Every command that takes ``--record FILE`` for the link it drives, with what else it needs.
RECORDING_COMMANDS = [
    ("send", "qd"),
    ("demo",),
    ("console",),
    ("monitor",),
    ("mavlink",),
    ("mqtt", "--broker", "mqtt://127.0.0.1:9", "--robot", "r1"),
]


@pytest.mark.parametrize("command", RECORDING_COMMANDS, ids=lambda command: command[0])
def test_a_malformed_url_leaves_no_recording(
    run_cli: RunCli, tmp_path: Path, command: tuple[str, ...]
) -> None:
    recording = tmp_path / "badurl.jsonl"
    name, *rest = command
    result = run_cli(name, "sim://?speed=3", *rest, "--record", str(recording))
    assert result.status == 2
    assert "unknown sim option 'speed'" in result.err
    assert not recording.exists()


@pytest.mark.integration
@pytest.mark.parametrize("command", RECORDING_COMMANDS, ids=lambda command: command[0])
@pytest.mark.usefixtures("monitor_on_a_terminal")
def test_a_link_that_does_not_open_leaves_no_recording(
    run_cli: RunCli, tmp_path: Path, command: tuple[str, ...]
) -> None:
    recording = tmp_path / "refused.jsonl"
    name, *rest = command
    url = f"socket://127.0.0.1:{_free_port()}"  # nobody listens: the connection is refused
    result = run_cli(name, url, *rest, "--record", str(recording))
    assert result.status == 1, result.err
    assert f"cannot open {url}" in result.err
    assert f"rovlink {name}: nothing was recorded; {recording} not kept" in result.err
    assert "recorded 1" not in result.err  # no summary of a recording of nothing
    assert not recording.exists()


@pytest.mark.integration
@pytest.mark.parametrize(
    "command", [*RECORDING_COMMANDS, ("record",)], ids=lambda command: command[0]
)
@pytest.mark.usefixtures("monitor_on_a_terminal")
def test_an_existing_recording_is_never_written_over(
    run_cli: RunCli, tmp_path: Path, command: tuple[str, ...]
) -> None:
    # Last week's dive.jsonl was truncated as the new recording opened, and removed with it
    # when the link then did not open (a recording of its header alone is not kept).
    recording = tmp_path / "dive.jsonl"
    recording.write_bytes(b"last week's dive\n")
    name, *rest = command
    url = f"socket://127.0.0.1:{_free_port()}"  # nobody listens: the connection is refused
    option = "-o" if name == "record" else "--record"
    result = run_cli(name, url, *rest, option, str(recording))
    assert result.status == 1, result.err
    assert f"cannot record to {recording}: {recording} exists already" in result.err
    assert "cannot open" not in result.err  # refused before the link is opened
    assert recording.read_bytes() == b"last week's dive\n"


@pytest.mark.integration
@pytest.mark.parametrize("command", [("send", "sim://", "qd"), ("record",)], ids=["send", "record"])
def test_a_named_pipe_is_recorded_into_not_refused_as_a_recording_already_there(
    run_cli: RunCli, tmp_path: Path, command: tuple[str, ...]
) -> None:
    # The recipe of docs/recording.md (mkfifo live.jsonl, then record to it) was refused:
    # "live.jsonl exists already (a recording is never written over…)"; a pipe holds nothing.
    fifo = tmp_path / "live.jsonl"
    os.mkfifo(fifo)
    copy = tmp_path / "copy.jsonl"
    reader = threading.Thread(target=lambda: copy.write_bytes(fifo.read_bytes()), daemon=True)
    reader.start()
    if command == ("record",):
        with running_sim("--tcp", "127.0.0.1:0", "--seed", "1") as sim:
            assert sim.tcp_url is not None
            tap = f"socket://127.0.0.1:{_free_port()}"
            args = ("record", sim.tcp_url, "-o", str(fifo), "--tap", tap, "--duration", "1")
            result = run_cli(*args)
    else:
        result = run_cli(*command, "--record", str(fifo))
    reader.join(timeout=10)
    assert result.status == 0, result.err
    assert "exists already" not in result.err
    assert fifo.exists()  # (the reader's pipe is left where it was made)
    assert isinstance(next(read_entries(str(copy))), HeaderEntry)


def test_a_directory_named_as_the_recording_is_said_to_be_one(
    run_cli: RunCli, tmp_path: Path
) -> None:
    directory = tmp_path / "dive.mcap"
    directory.mkdir()
    result = run_cli("send", "sim://", "qd", "--record", str(directory))
    assert result.status == 1
    assert result.err == f"rovlink send: cannot record to {directory}: Is a directory\n"


def test_overwrite_writes_over_a_recording_already_there(run_cli: RunCli, tmp_path: Path) -> None:
    recording = tmp_path / "service.jsonl"
    recording.write_bytes(b"the last run's recording\n")
    result = run_cli("send", "sim://", "qd", "--record", str(recording), "--overwrite")
    assert result.status == 0, result.err
    assert isinstance(next(read_entries(str(recording))), HeaderEntry)


def test_overwrite_with_rotation_removes_the_earlier_rotations_files(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # A service that records to one name with --overwrite --split: the last run's dive.002 and
    # dive.003, which the new run never reached, were left beside its dive.jsonl and dive.001,
    # and read as the new dive's later parts.
    recording = tmp_path / "dive.jsonl"
    earlier = [tmp_path / f"dive.{index:03d}.jsonl" for index in (1, 2, 3)]
    for path in (recording, *earlier):
        path.write_bytes(b"the last run's recording\n")
    other = tmp_path / "other.001.jsonl"  # another recording's file: left alone
    other.write_bytes(b"another recording\n")
    result = run_cli(
        "send", "sim://", "qd", "--record", str(recording), "--split", "1h", "--overwrite"
    )
    assert result.status == 0, result.err
    assert isinstance(next(read_entries(str(recording))), HeaderEntry)
    assert [path for path in earlier if path.exists()] == []
    assert other.read_bytes() == b"another recording\n"


def test_a_rotation_never_writes_over_an_earlier_rotations_file(
    run_cli: RunCli, tmp_path: Path
) -> None:
    earlier = tmp_path / "dive.001.jsonl"
    earlier.write_bytes(b"an earlier dive's second file\n")
    recording = tmp_path / "dive.jsonl"
    result = run_cli("send", "sim://", "qd", "--record", str(recording), "--split", "1s")
    assert result.status == 1, result.err
    assert f"cannot record to {recording}: {earlier} exists already" in result.err
    assert earlier.read_bytes() == b"an earlier dive's second file\n"
    assert not recording.exists()
    # Without rotation the files of an earlier rotation are not in the way.
    result = run_cli("send", "sim://", "qd", "--record", str(recording))
    assert result.status == 0, result.err
    assert earlier.read_bytes() == b"an earlier dive's second file\n"


@pytest.mark.integration
def test_record_to_a_directory_not_there_is_refused_before_the_link_opens(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # Before, the link was opened (a board that resets as its port opens, reset) and the tap
    # served first, and the file refused after.
    output = tmp_path / "missing" / "dive.mcap"
    url = f"socket://127.0.0.1:{_free_port()}"  # nobody listens: opening it would fail
    result = run_cli("record", url, "-o", str(output))
    assert result.status == 2
    assert result.err.splitlines()[-1] == (
        f"rovlink record: error: -o {output}: no such directory: {output.parent}"
    )


@pytest.mark.integration
def test_a_tap_other_computers_reach_needs_allow_remote(run_cli: RunCli, tmp_path: Path) -> None:
    # Before, --tap socket://0.0.0.0:PORT served the robot to the whole network with no word:
    # anyone reaching it drove the robot, unauthenticated (fault and controller refuse so).
    recording = tmp_path / "tapped.jsonl"
    tap = "socket://0.0.0.0:0"
    result = run_cli("record", "sim://", "-o", str(recording), "--tap", tap, "--duration", "0.1")
    assert result.status == 2
    assert result.err.splitlines()[-1] == (
        f"rovlink record: error: --tap {tap}: 0.0.0.0 is not a loopback address, and the "
        "protocol has no authentication; add --allow-remote to let other computers drive the robot"
    )
    assert not recording.exists()
    result = run_cli(
        "record",
        "sim://",
        "-o",
        str(recording),
        "--tap",
        tap,
        "--duration",
        "0.1",
        "--allow-remote",
    )
    assert result.status == 0, result.err


def test_a_rotated_recording_of_headers_alone_counts_as_nothing_recorded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Each file of a rotation starts with its own header: a link that failed slowly under
    # --split left several header-only files, which were reported as a recording.
    monkeypatch.setattr("rovlink.recorder.recorder.FLUSH_INTERVAL_S", 0.05)  # (rotation's pace)
    idle = Recorder(str(tmp_path / "idle.jsonl"), split_s=0.05)
    deadline = time.monotonic() + 10.0
    while len(idle.paths) < 3 and time.monotonic() < deadline:
        time.sleep(0.01)  # (polling the recorder's own rotation, bounded)
    idle.close()
    assert len(idle.paths) >= 3
    assert recorded_nothing(idle)

    busy = Recorder(str(tmp_path / "busy.jsonl"))
    with rovlink.connect("sim://", on_event=busy.on_event) as rov:
        rov.depth_cm()
    busy.close()
    assert not recorded_nothing(busy)


@pytest.mark.integration
def test_record_on_a_busy_link_fails_says_why_and_keeps_no_file(
    run_cli: RunCli, tmp_path: Path
) -> None:
    output = tmp_path / "busy.mcap"
    with running_sim("--tcp", "127.0.0.1:0") as sim:
        assert sim.tcp_url is not None
        host, port = sim.tcp_url.removeprefix("socket://").rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=20) as first:
            first.sendall(b"#qd!")  # served, once it answers: the simulator is now busy
            assert first.recv(64).startswith(b"$qd.")
            result = run_cli("record", sim.tcp_url, "-o", str(output), "--duration", "60")
    assert result.status == 1, result.err
    assert 'it said: "busy: the simulated controller already has a client"' in result.err
    assert f"nothing was recorded; {output} not kept" in result.err
    assert not output.exists()


class _ClosingController:
    """A TCP 'controller' that answers once and then closes the connection."""

    def __init__(self, said: bytes) -> None:
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.url = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        self._said = said
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        connection, _ = self._listener.accept()
        with connection:
            connection.sendall(self._said)

    def close(self) -> None:
        self._thread.join(20)
        self._listener.close()


@pytest.mark.integration
def test_record_of_a_link_lost_mid_recording_keeps_the_file_and_fails(
    run_cli: RunCli, tmp_path: Path
) -> None:
    output = tmp_path / "lost.jsonl"
    controller = _ClosingController(b"#qd!$qd.5!")
    try:
        result = run_cli(
            "record", controller.url, "-o", str(output), "--duration", "60", "--exit-on-loss"
        )
    finally:
        controller.close()
    assert result.status == 1, result.err
    assert "closed by the other end; the recording ends here" in result.err
    entries = list(read_entries(str(output)))
    frames = [(e.kind, e.name) for e in entries if isinstance(e, FrameEntry)]
    assert frames == [("command", "qd"), ("response", "qd")]
    # The file says why it ends (it ended as if its recorder had been stopped by hand).
    last = entries[-1]
    assert isinstance(last, EventEntry)
    assert (last.event, last.name) == ("link", "lost")
    assert "closed by the other end" in last.detail


def test_decode_of_a_recording_starts_in_its_headers_mode(run_cli: RunCli, tmp_path: Path) -> None:
    path = tmp_path / "checked.jsonl"
    wire = encode(Command("qd"), "crc8") + encode(Response("qd", (5,)), "crc8")
    _write(
        path,
        HeaderEntry(1.0, 1, "sim://", True, "crc8", "test", "0"),
        WireEntry(2.0, 2, "in", wire),
    )
    result = run_cli("decode", str(path), "--stats")
    assert result.status == 0, result.err
    assert json.loads(result.out)["events"] == {"frame": 2}
    # Said on the command line, the mode is the one asked for.
    forced = run_cli("decode", str(path), "--stats", "--no-checksum")
    assert json.loads(forced.out)["events"] == {"error": 2}


def test_decode_of_a_recording_takes_the_mode_and_the_algorithm_each_as_given(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # docs/tools.md: the header's mode and algorithm, unless they are given. Before, a given
    # --algorithm was ignored unless --checksum was given too, and a given --checksum threw
    # away the header's algorithm.
    path = tmp_path / "xor.jsonl"
    wire = encode(Command("qd"), "xor") + encode(Response("qd", (5,)), "xor")
    _write(
        path,
        HeaderEntry(1.0, 1, "sim://", True, "xor", "test", "0"),
        WireEntry(2.0, 2, "in", wire),
    )
    as_recorded = run_cli("decode", str(path), "--stats", "--checksum")
    assert as_recorded.status == 0, as_recorded.err
    assert json.loads(as_recorded.out)["events"] == {"frame": 2}
    other = run_cli("decode", str(path), "--stats", "--algorithm", "crc8")
    assert other.status == 0, other.err
    assert json.loads(other.out)["events"] == {"error": 2}
    assert json.loads(other.out)["reasons"] == {"checksum": 2}


def test_decode_of_a_recording_reads_each_reply_in_its_querys_mode(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # P3: the qd sent just before #crcon! is answered plain, after the mode frame went out.
    path = tmp_path / "switch.jsonl"
    checked_query = encode(Command("qd"), "crc8")
    _write(
        path,
        HeaderEntry(1.0, 1, "sim://", False, "crc8", "test", "0"),
        WireEntry(2.0, 2, "out", b"#qd!#crcon!" + checked_query),
        WireEntry(3.0, 3, "in", encode(Response("qd", (5,))) + b"$qd.6"),
        WireEntry(4.0, 4, "in", encode(Response("qd", (6,)), "crc8")[5:]),
    )
    result = run_cli("decode", str(path))
    assert result.status == 0, result.err
    shown = [json.loads(line) for line in result.out.splitlines()]
    assert [(e["direction"], e["event"], e["name"], e.get("query")) for e in shown] == [
        ("out", "frame", "qd", None),
        ("out", "frame", "crcon", None),
        ("out", "frame", "qd", None),
        ("in", "frame", "qd", "qd"),
        ("in", "frame", "qd", "qd"),
    ]
    assert [e["values"] for e in shown if e["direction"] == "in"] == [[5], [6]]


def test_each_rotated_file_records_the_mode_in_force_as_it_starts(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("rovlink.recorder.recorder.FLUSH_INTERVAL_S", 0.05)  # (rotation's pace)
    recorder = Recorder(str(tmp_path / "tap.jsonl"), split_s=0.05)
    recorder.on_bytes("out", b"#crcon!")
    deadline = time.monotonic() + 10.0
    while len(recorder.paths) < 2 and time.monotonic() < deadline:
        time.sleep(0.01)  # (polling the recorder's own rotation, bounded)
    checked = encode(Command("qd"), "crc8") + encode(Response("qd", (7,)), "crc8")
    recorder.on_bytes("out", checked[:6])
    recorder.on_bytes("in", checked[6:])
    recorder.close()
    assert len(recorder.paths) >= 2
    headers = [next(iter(read_entries(path))) for path in recorder.paths]
    assert [header.checksum for header in headers if isinstance(header, HeaderEntry)] == [
        False,
        *[True] * (len(recorder.paths) - 1),
    ]
    result = run_cli("decode", recorder.paths[-1], "--stats")
    assert json.loads(result.out)["events"] == {"frame": 2}


@pytest.mark.parametrize("cut_bytes", [0, 8, 40], ids=lambda n: f"{n}-bytes")
@pytest.mark.parametrize("command", ["replay", "decode"])
def test_an_mcap_cut_before_its_first_entry_ends_early_without_an_error(
    run_cli: RunCli, tmp_path: Path, cut_bytes: int, command: str
) -> None:
    # A recorder killed in its first second leaves an empty file, or one cut after its start.
    whole = tmp_path / "whole.mcap"
    _record(whole)
    path = tmp_path / "killed.mcap"
    path.write_bytes(whole.read_bytes()[:cut_bytes])
    result = run_cli(command, str(path))
    assert result.status == 0, result.err
    assert result.err.startswith(f"rovlink {command}: {path}: ")
    assert "read 0 entries" in result.err
    assert "()" not in result.err


def test_a_foreign_file_named_mcap_says_what_it_is_not_with_a_reason(
    run_cli: RunCli, tmp_path: Path
) -> None:
    path = tmp_path / "notes.mcap"
    path.write_bytes(b"hello")
    result = run_cli("replay", str(path))
    assert result.status == 1
    assert f"{path}: not an MCAP recording (" in result.err
    assert "()" not in result.err


@pytest.mark.integration
@pytest.mark.parametrize(
    ("how", "status"),
    [(signal.SIGINT, 130), (signal.SIGTERM, 0), (signal.SIGHUP, 0), (signal.SIGQUIT, 130)],
)
def test_record_ends_on_ctrl_c_with_130_and_on_a_service_stop_with_0(
    tmp_path: Path, how: signal.Signals, status: int
) -> None:
    output = tmp_path / "tapped.jsonl"
    with running_sim("--tcp", "127.0.0.1:0", "--seed", "1") as sim:
        assert sim.tcp_url is not None
        recorder = _start_recording(sim.tcp_url, output, "pty")
        try:
            assert recorder.stderr is not None
            found = re.search(r"program's side: (\S+);", recorder.stderr.readline())
            assert found
            with rovlink.connect(found.group(1)) as rov:
                rov.depth_cm()
        finally:
            recorder.send_signal(how)
            _, err = recorder.communicate(timeout=20)
    assert recorder.returncode == status, err
    assert "recorded" in err  # the file finished either way


@pytest.mark.integration
def test_a_driving_command_whose_link_is_lost_ends_its_recording_saying_so(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # Its recording ended as one of a session that ended well: nothing in the file said the
    # link was lost (only the command's last line, gone with the terminal).
    output = tmp_path / "lost.jsonl"
    # The connect probe and the first qd answered; at the second, the controller hangs up.
    controller = FakeControllerServer(script=("reply", "reply", "close"))
    try:
        result = run_cli("send", controller.url, "--record", str(output), "qd", "qd", "qd")
    finally:
        controller.close()
    assert result.status == 1, result.err
    assert "connection lost" in result.err
    last = list(read_entries(str(output)))[-1]
    assert isinstance(last, EventEntry)
    assert (last.event, last.name) == ("link", "lost")
    assert "closed by the other end" in last.detail


def test_record_reply_timeout_is_the_tapped_programs_own(tmp_path: Path) -> None:
    # A program polling every 50 ms that waits 40 ms for a reply: one lost reply shifted
    # every later round trip by a poll (51 ms instead of 1 ms) under the default 0.5 s.
    from rovlink.cli import build_parser
    from rovlink.cli.recording import open_recorder

    output = tmp_path / "tap.jsonl"
    argv = ["record", "sim://", "-o", str(output), "--tap", "pty", "--reply-timeout", "0.04"]
    args = build_parser("record").parse_args(argv)
    with open_recorder(args, str(output), url="sim://", program="test", checksum=False) as rec:
        rec.on_bytes("out", b"#qd!", at_s=1.0)  # its reply lost
        for at_s in (1.05, 1.1):
            rec.on_bytes("out", b"#qd!", at_s=at_s)
            rec.on_bytes("in", b"$qd.7!", at_s=at_s + 0.001)
    frames = [e for e in read_entries(str(output)) if isinstance(e, FrameEntry)]
    assert [f.round_trip_ms for f in frames if f.kind == "response"] == [1.0, 1.0]
