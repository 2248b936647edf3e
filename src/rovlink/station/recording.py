"""The station's record button: recordings of the robot's link started and stopped from the
page, written to one directory and downloaded from it.

A recording holds what every recording of rovlink holds (:mod:`rovlink.recorder`): every byte,
frame, event and the telemetry, to an ``.mcap`` file that Foxglove opens and ``rovlink replay``
and ``rovlink plot`` read. The station hands every event of the link to :meth:`on_event`; it
goes to the recorder while one runs and is dropped otherwise. Only the finished recordings of
this station can be downloaded, by name: no path from a page ever reaches the file system.
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rovlink.client.events import ClientEvent
from rovlink.recorder import Recorder
from rovlink.recorder import RecordingError as RecorderError

__all__ = ["FinishedRecording", "RecordingError", "StationRecordings"]


class RecordingError(Exception):
    """A start or stop the station cannot do; the text says why, for the page."""


@dataclass(frozen=True)
class FinishedRecording:
    """A recording that can be downloaded."""

    name: str
    path: Path
    size_bytes: int
    duration_s: float


class StationRecordings:
    """Recordings of one station's link, in ``directory`` (made when the first one starts)."""

    def __init__(self, directory: Path, *, url: str, checksum: bool, algorithm: str) -> None:
        self.directory = directory
        self._url = url
        self._checksum = checksum
        self._algorithm = algorithm
        self._recorder: Recorder | None = None
        self._started_s = 0.0
        self._started_by = ""
        self.finished: dict[str, FinishedRecording] = {}
        #: Why the running recording stopped by itself (a full disk), if it did.
        self.failure: str | None = None

    @property
    def active(self) -> bool:
        """Whether a recording runs."""
        return self._recorder is not None

    def on_event(self, event: ClientEvent) -> None:
        """The link's event hook: to the recorder while one runs."""
        recorder = self._recorder
        if recorder is not None:
            recorder.on_event(event)

    def start(self, who: str) -> str:
        """Start recording; the file's name."""
        if self._recorder is not None:
            raise RecordingError(f"already recording to {Path(self._recorder.path).name}")
        name = time.strftime("rovlink-%Y%m%d-%H%M%S.mcap")
        path = self.directory / name
        suffix = 1
        while path.exists() or path.name in self.finished:
            path = self.directory / f"{name[:-5]}-{suffix}.mcap"
            suffix += 1
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._recorder = Recorder(
                str(path),
                url=self._url,
                checksum=self._checksum,
                algorithm=self._algorithm,
                program="rovlink web",
                on_failure=self._failed,
            )
        except OSError as error:
            raise RecordingError(f"cannot record to {path}: {error.strerror}") from None
        except RecorderError as error:  # the mcap library missing
            raise RecordingError(str(error)) from None
        self._started_s = time.monotonic()
        self._started_by = who
        self.failure = None
        return path.name

    async def stop(self) -> FinishedRecording:
        """Stop the running recording and finish its file (on a worker thread: finishing
        writes the file's index)."""
        recorder = self._recorder
        if recorder is None:
            raise RecordingError("not recording")
        self._recorder = None
        await asyncio.get_running_loop().run_in_executor(None, recorder.close)
        path = Path(recorder.path)
        size = sum(Path(part).stat().st_size for part in recorder.paths if Path(part).exists())
        finished = FinishedRecording(
            path.name, path, size, round(time.monotonic() - self._started_s, 1)
        )
        self.finished[path.name] = finished
        return finished

    def file(self, name: str) -> Path | None:
        """The file of a finished recording called ``name`` (``None`` for any other name)."""
        finished = self.finished.get(name)
        return finished.path if finished is not None else None

    def state(self) -> dict[str, Any]:
        """What the pages show: the running recording, if any, and the finished ones."""
        recorder = self._recorder
        return {
            "type": "recording",
            "active": recorder is not None,
            "file": Path(recorder.path).name if recorder is not None else None,
            "started_by": self._started_by if recorder is not None else None,
            "elapsed_s": round(time.monotonic() - self._started_s, 1) if recorder else None,
            "failure": self.failure,
            "finished": [
                {"name": item.name, "size_bytes": item.size_bytes, "duration_s": item.duration_s}
                for item in self.finished.values()
            ],
        }

    def _failed(self, message: str) -> None:
        self.failure = message  # the writer's thread: the next state the pages get says it
