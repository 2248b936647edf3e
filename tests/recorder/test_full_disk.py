"""A sink on a full disk (``/dev/full``: every write that reaches it fails with ENOSPC) raises
from ``close`` and still closes its file: no descriptor is left to a long-running station."""

from __future__ import annotations

import argparse
import errno
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

import rovlink
from rovlink.cli.recording import open_recorder
from rovlink.logs import WarningsShownBy
from rovlink.recorder import Recorder, read_entries
from rovlink.recorder.entries import TELEMETRY_FIELDS, Entry, HeaderEntry, TelemetryEntry
from rovlink.recorder.formats import open_sink
from rovlink.recorder.sink import Sink

_NO_DEV_FULL = pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")

#: Far more than the file's buffer, so that the disk is reached before close.
_ENTRIES = 400


def _entries() -> list[Entry]:
    now_s, wall_ns = time.monotonic(), time.time_ns()
    header = HeaderEntry(now_s, wall_ns, "sim://", False, "crc8", "test", "0")
    reading = TelemetryEntry(now_s, wall_ns, dict.fromkeys(TELEMETRY_FIELDS, 1))
    return [header, *([reading] * _ENTRIES)]


def _descriptors_to(device: str) -> list[str]:
    found = []
    for fd in os.listdir("/proc/self/fd"):
        try:
            if os.readlink(f"/proc/self/fd/{fd}") == device:
                found.append(fd)
        except OSError:
            pass  # closed meanwhile (the listing's own descriptor)
    return found


@_NO_DEV_FULL
@pytest.mark.parametrize("suffix", [".mcap", ".jsonl", ".csv", ".bin"])
def test_a_sink_on_a_full_disk_closes_its_file(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"dive{suffix}"
    path.symlink_to("/dev/full")
    before = _descriptors_to("/dev/full")
    sink = open_sink(str(path))
    try:
        for entry in _entries():
            sink.write(entry)
    except OSError:
        pass  # a write that reached the disk: as the recorder's writer would see it
    with pytest.raises(OSError, match=r"Errno (28|22)"):  # ENOSPC, or EINVAL: fsync, a device
        sink.close()
    assert _descriptors_to("/dev/full") == before
    sink.close()  # once closed, closing again does nothing


class _FillingSink:
    """A real sink whose flushes and close fail as on a full disk once ``full`` is set (the
    bytes it buffered never reach the file)."""

    def __init__(self, real: Sink, full: threading.Event) -> None:
        self.real = real
        self.unit = real.unit
        self._full = full

    def _check(self) -> None:
        if self._full.is_set():
            raise OSError(errno.ENOSPC, "No space left on device")

    def write(self, entry: Entry) -> None:
        self.real.write(entry)

    def flush(self) -> None:
        self._check()
        self.real.flush()

    def close(self) -> None:
        self._check()
        self.real.close()

    def size_bytes(self) -> int:
        return self.real.size_bytes()

    def held(self) -> int:
        return self.real.held()


def _until(condition: Callable[[], bool], timeout_s: float = 10.0) -> None:
    deadline_s = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline_s, "condition not met in time"
        time.sleep(0.01)


def test_after_a_full_disk_a_recorder_counts_only_what_was_made_durable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    full = threading.Event()
    sinks: list[_FillingSink] = []

    def filling(path: str) -> Sink:
        sinks.append(_FillingSink(open_sink(path), full))
        return sinks[-1]

    monkeypatch.setattr("rovlink.recorder.recorder.open_sink", filling)
    path = tmp_path / "dive.jsonl"
    recorder = Recorder(str(path), url="sim://")
    with rovlink.connect("sim://", on_event=recorder.on_event) as rov:
        rov.depth_cm()
        _until(lambda: recorder.held() > 0)  # the writer's first flush: made durable
        durable = recorder.held()
        full.set()
        rov.depth_cm()  # more entries, which the disk will not take
        _until(lambda: recorder.error is not None)
    recorder.close()
    assert recorder.entries_written > durable
    assert recorder.held() == durable
    sinks[-1].real.close()  # what the disk took before it filled up
    assert len(list(read_entries(str(path)))) >= durable


@pytest.mark.parametrize("told", [True, False], ids=["on_failure", "no callback"])
def test_a_full_disk_is_reported_once(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
    told: bool,
) -> None:
    # The command line prints its own line from on_failure: the log's ERROR line came too.
    full = threading.Event()
    monkeypatch.setattr(
        "rovlink.recorder.recorder.open_sink", lambda path: _FillingSink(open_sink(path), full)
    )
    reports: list[str] = []
    recorder = Recorder(
        str(tmp_path / "dive.jsonl"), url="sim://", on_failure=reports.append if told else None
    )
    with rovlink.connect("sim://", on_event=recorder.on_event) as rov:
        full.set()
        rov.depth_cm()
        _until(lambda: recorder.error is not None)
    recorder.close()
    logged = [r for r in caplog.records if r.name == "rovlink.recorder.recorder"]
    assert reports == ([recorder.error] if told else [])
    assert [r.levelname for r in logged if r.levelname == "ERROR"] == ([] if told else ["ERROR"])


def test_the_command_lines_recording_that_stops_is_shown_with_the_librarys_warnings(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The dashboard and the console hold the terminal and show the library's warnings on it; a
    # line the command printed to stderr instead was never seen there.
    full = threading.Event()
    monkeypatch.setattr(
        "rovlink.recorder.recorder.open_sink", lambda path: _FillingSink(open_sink(path), full)
    )
    shown: list[str] = []
    warnings = WarningsShownBy(lambda message, level: shown.append(message))
    warnings.attach()
    try:
        args = argparse.Namespace(max_size=None, split=None, checksum=False, algorithm="crc8")
        path = str(tmp_path / "dive.jsonl")
        recorder = open_recorder(
            args, path, url="sim://", program="rovlink monitor", checksum=False
        )
        with rovlink.connect("sim://", on_event=recorder.on_event) as rov:
            full.set()
            rov.depth_cm()
            _until(lambda: recorder.error is not None)
        recorder.close()
    finally:
        warnings.detach()
    assert shown == [f"{recorder.error} (the link goes on)"]


def test_sync_makes_the_session_so_far_durable_or_says_why_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A command asks before it ends, while it can still stop the robot: before, a full disk
    # showed only once the file was closed, after the command had ended with status 0.
    full = threading.Event()
    monkeypatch.setattr(
        "rovlink.recorder.recorder.open_sink", lambda path: _FillingSink(open_sink(path), full)
    )
    path = tmp_path / "dive.jsonl"
    recorder = Recorder(str(path), url="sim://", on_failure=lambda reason: None)
    with rovlink.connect("sim://", on_event=recorder.on_event) as rov:
        rov.depth_cm()
        assert recorder.sync() is None
        assert recorder.held() == recorder.entries_written  # all of it, durable
        assert any(isinstance(entry, TelemetryEntry) for entry in read_entries(str(path)))
        full.set()
        rov.depth_cm()
        assert recorder.sync() == f"recording to {path} stopped: No space left on device"
    recorder.close()
    assert recorder.sync() == recorder.error  # (at once, once the writer has ended)
