"""Recordings of real sessions with the simulated controller, made once per test."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

import rovlink
from rovlink.recorder import Recorder

MakeRecording = Callable[[str], Recorder]


def drive_a_short_dive(rov: rovlink.Client) -> None:
    """Unlock, set a depth, poll every sensor, move, stop: every kind of frame."""
    rov.start()
    rov.hold_depth(40)
    for _ in range(5):
        rov.sensors()
        rov.depth_cm()
    rov.move(90, 20)
    rov.leak_detected()
    rov.stop()


@pytest.fixture
def make_recording(tmp_path: Path) -> MakeRecording:
    """Record a short dive on ``sim://?seed=1`` to ``tmp_path/NAME`` and return the recorder."""

    def make(name: str) -> Recorder:
        path = str(tmp_path / name)
        recorder = Recorder(path, url="sim://?seed=1")
        with recorder, rovlink.connect("sim://?seed=1", on_event=recorder.on_event) as rov:
            drive_a_short_dive(rov)
        return recorder

    return make
