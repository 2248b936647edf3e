"""An IMU that did not start, started again in the background while the controller runs.

A BNO055 needs about 650 ms after power-on before it answers, and a transient I²C error at
start leaves it unstarted just as well; the controller starts without it (the pilot can drive
without attitude). Its driver's start takes about a second (a reset, then mode changes), so it
runs on a thread of its own, never in the control loop, at most once every
``IMU_RETRY_INTERVAL_S``; once it has started, the chip is polled as one that started at once.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

from rovlink.board.pi.bno055 import Bno055Imu
from rovlink.board.sensors import SensorError
from rovlink.controller import Attitude
from rovlink.logs import get_logger

__all__ = ["IMU_RETRY_INTERVAL_S", "ImuStartedInBackground"]

logger = get_logger(__name__)

#: Seconds between the end of a failed start of the IMU and the next try.
IMU_RETRY_INTERVAL_S = 1.0


class ImuStartedInBackground:
    """The source of an IMU that did not start: each poll fails, saying why, while the chip is
    started again on a background thread (one try at a time, the next
    ``IMU_RETRY_INTERVAL_S`` after one failed); once it starts, polls read it.

    ``where`` names the chip and its bus for the log; ``on_started`` runs (on the control
    loop's thread, at the first poll after the start) when it has started.
    """

    def __init__(
        self,
        imu: Bno055Imu,
        where: str,
        why: str,
        *,
        on_started: Callable[[], None] | None = None,
        retry_interval_s: float = IMU_RETRY_INTERVAL_S,
    ) -> None:
        self._imu = imu
        self._where = where
        self._why = why
        self._on_started = on_started
        self._retry_interval_s = retry_interval_s
        self._next_try_s: float | None = None
        self._thread: threading.Thread | None = None
        self._started = False
        self._closed = threading.Event()
        self._last_error: Exception | None = None
        #: Tries so far (the start's failure not counted).
        self.tries = 0

    @property
    def trying(self) -> bool:
        """Whether a start is under way on the background thread."""
        return self._thread is not None and self._thread.is_alive()

    def poll(self, now_s: float) -> Attitude | None:
        """The chip's reading once started; before that, :class:`SensorError` (and a try, if
        one is due and none is under way)."""
        if self._started:
            return self._imu.poll(now_s)
        thread = self._thread
        if thread is not None and not thread.is_alive():
            thread.join()
            self._thread = None
            if self._last_error is None:
                self._started = True
                logger.warning(
                    "%s started after %d %s: roll, pitch and heading are measured again",
                    self._where,
                    self.tries,
                    "try" if self.tries == 1 else "tries",
                )
                if self._on_started is not None:
                    self._on_started()
                return self._imu.poll(now_s)
            self._why = f"not answering ({self._last_error})"
            self._next_try_s = now_s + self._retry_interval_s
        if self._next_try_s is None:
            self._next_try_s = now_s + self._retry_interval_s
        if self._thread is None and now_s >= self._next_try_s and not self._closed.is_set():
            self.tries += 1
            self._last_error = None
            self._thread = threading.Thread(target=self._start, name="imu-start", daemon=True)
            self._thread.start()
        raise SensorError(f"{self._why}; started again every {self._retry_interval_s:g} s")

    def close(self, timeout_s: float = 2.0) -> None:
        """Start no more tries and wait (up to ``timeout_s``) for one under way, before the
        bus is closed."""
        self._closed.set()
        thread = self._thread
        if thread is not None:
            thread.join(timeout_s)

    def _start(self) -> None:
        try:
            self._imu.start()
        except Exception as error:  # a library's own as well: the thread must say why
            self._last_error = error
            logger.debug("%s: start failed: %s", self._where, error, exc_info=True)
