"""A sink on a full disk (``/dev/full``: every write that reaches it fails with ENOSPC) raises
from ``close`` and still closes its file: no descriptor is left to a long-running station."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from rovlink.recorder.entries import TELEMETRY_FIELDS, Entry, HeaderEntry, TelemetryEntry
from rovlink.recorder.formats import open_sink

pytestmark = pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full here")

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
