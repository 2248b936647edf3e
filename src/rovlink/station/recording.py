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
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rovlink.client.events import ClientEvent
from rovlink.logs import get_logger
from rovlink.recorder import Recorder
from rovlink.recorder import RecordingError as RecorderError

__all__ = ["FinishedRecording", "RecordingError", "StationRecordings"]

logger = get_logger(__name__)


class RecordingError(Exception):
    """A start or stop the station cannot do; the text says why, for the page."""


@dataclass(frozen=True)
class FinishedRecording:
    """A recording that can be downloaded."""

    name: str
    path: Path
    size_bytes: int
    duration_s: float
    #: It stopped by itself (a full disk): it holds what was written until then.
    failed: bool = False


class StationRecordings:
    """Recordings of one station's link, in ``directory`` (made when the first one starts).

    A recording that stops by itself (a full disk) ends at once: it is listed with the length
    it has, :attr:`failure` says why until the next one starts, and the listeners given to
    :meth:`add_failure_listener` are called with the reason on the event loop.
    """

    def __init__(
        self,
        directory: Path,
        *,
        url: str,
        checksum: bool,
        algorithm: str,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.directory = directory
        self._url = url
        self._checksum = checksum
        self._algorithm = algorithm
        self._clock = clock
        self._recorder: Recorder | None = None
        self._started_s = 0.0
        self._started_by = ""
        #: When the writer's thread saw the running recording fail (``clock``).
        self._failed_at_s: float | None = None
        self._failure_listeners: list[Callable[[str], None]] = []
        self._closing: set[asyncio.Future[None]] = set()
        self.finished: dict[str, FinishedRecording] = {}
        #: Why the last recording stopped by itself (a full disk), until the next one starts.
        self.failure: str | None = None

    @property
    def active(self) -> bool:
        """Whether a recording runs."""
        return self._recorder is not None

    def add_failure_listener(self, listener: Callable[[str], None]) -> None:
        """Call ``listener(reason)`` (on the event loop) when a recording stops by itself."""
        self._failure_listeners.append(listener)

    def on_event(self, event: ClientEvent) -> None:
        """The link's event hook: to the recorder while one runs."""
        recorder = self._recorder
        if recorder is not None:
            recorder.on_event(event)

    def start(self, who: str) -> str:
        """Start recording (on the event loop); the file's name."""
        if self._recorder is not None:
            raise RecordingError(f"already recording to {Path(self._recorder.path).name}")
        name = time.strftime("rovlink-%Y%m%d-%H%M%S.mcap")
        path = self.directory / name
        suffix = 1
        while path.exists() or path.name in self.finished:
            path = self.directory / f"{name[:-5]}-{suffix}.mcap"
            suffix += 1
        loop = asyncio.get_running_loop()

        def failed(reason: str) -> None:  # on the writer's thread
            logger.error("%s (the link goes on)", reason)  # (the terminal's line)
            self._failed_at_s = self._clock()
            loop.call_soon_threadsafe(self._end_failed, str(path), reason)

        self._failed_at_s = None
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._recorder = Recorder(
                str(path),
                url=self._url,
                checksum=self._checksum,
                algorithm=self._algorithm,
                program="rovlink web",
                on_failure=failed,
            )
        except OSError as error:
            raise RecordingError(f"cannot record to {path}: {error.strerror}") from None
        except RecorderError as error:  # the mcap library missing
            raise RecordingError(str(error)) from None
        self._started_s = self._clock()
        self._started_by = who
        self.failure = None
        return path.name

    async def stop(self) -> FinishedRecording:
        """Stop the running recording and finish its file (on a worker thread: finishing
        writes the file's index)."""
        recorder = self._recorder
        if recorder is None:
            failed = f" (the last one stopped by itself: {self.failure})" if self.failure else ""
            raise RecordingError(f"not recording{failed}")
        self._recorder = None
        await asyncio.get_running_loop().run_in_executor(None, recorder.close)
        if recorder.error is not None:  # it failed while stopping: say so as if it had ended
            self.failure = recorder.error
        return self._finish(recorder)

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
            "elapsed_s": round(self._clock() - self._started_s, 1) if recorder else None,
            "failure": self.failure,
            "finished": [
                {
                    "name": item.name,
                    "size_bytes": item.size_bytes,
                    "duration_s": item.duration_s,
                    "failed": item.failed,
                }
                for item in self.finished.values()
            ],
        }

    def _finish(self, recorder: Recorder) -> FinishedRecording:
        """List a recording that ended: its size on disk and its length up to its end (the
        failure, if it failed)."""
        path = Path(recorder.path)
        size = sum(Path(part).stat().st_size for part in recorder.paths if Path(part).exists())
        failed_at_s = self._failed_at_s if recorder.error is not None else None
        ended_s = failed_at_s if failed_at_s is not None else self._clock()
        finished = FinishedRecording(
            path.name,
            path,
            size,
            round(ended_s - self._started_s, 1),
            failed=recorder.error is not None,
        )
        self.finished[path.name] = finished
        return finished

    def _end_failed(self, path: str, reason: str) -> None:
        """On the event loop: the recording at ``path`` stopped by itself (its file is closed
        already); it ends now, unless the pilot stopped it meanwhile."""
        recorder = self._recorder
        if recorder is None or recorder.path != path:
            return
        self._recorder = None
        self.failure = reason
        self._finish(recorder)
        # The writer's thread ends right after telling us; its join is left to a worker.
        closing = asyncio.get_running_loop().run_in_executor(None, recorder.close)
        self._closing.add(closing)
        closing.add_done_callback(self._closing.discard)
        for listener in self._failure_listeners:
            listener(reason)
