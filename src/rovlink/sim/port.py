"""An in-process simulated controller behind a pyserial-like port (the host driver's ``sim://``).

The port runs the simulation on a daemon thread; :meth:`SimulatedPort.write` hands the bytes to
the controller at once, so a query's reply is ready to read when ``write`` returns.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from pathlib import Path
from types import TracebackType

import serial

from rovlink.controller import Controller
from rovlink.logs import get_logger
from rovlink.sim.pacing import TickSchedule
from rovlink.sim.robot import SimConfig, SimulatedRobot, load_sim_config
from rovlink.sim.vehicle import Vehicle

__all__ = ["SimulatedPort", "open_port"]

logger = get_logger(__name__)

#: Controller output kept for a reader that does not read (as a UART's buffer would overflow).
_MAX_BUFFERED_BYTES = 1 << 16
_YIELD_S = 50e-6  # between batches when running faster than real time
#: The longest a read waits before it looks again whether the port was closed (a close that
#: could not take the lock to wake it, see SimulatedPort.close).
_READ_SLICE_S = 0.05
#: How long close() waits for the lock (held by a reader that a signal handler interrupted).
_CLOSE_LOCK_WAIT_S = 0.1


class SimulatedPort:
    """A thread-safe stand-in for a serial port with a simulated controller on the other end.

    Until :meth:`start` the simulated time moves only through :meth:`advance` (deterministic
    tests); after it, a daemon thread steps the simulation at the control rate in real time, or
    as fast as the CPU allows. ``robot``, ``controller`` and ``vehicle`` are there to inspect
    and steer the simulation; hold :attr:`lock` while touching them from another thread.
    """

    #: A write never waits: the controller takes the bytes at once (the host driver's asyncio
    #: client writes it in its event loop's thread).
    writes_may_wait = False
    #: Setting :attr:`timeout` costs nothing (no device to reconfigure): a link may set it
    #: before each read, so that a read waits its own time.
    timeout_is_free = True

    def __init__(
        self,
        robot_config: SimConfig | None = None,
        *,
        seed: int | None = None,
        timeout: float | None = None,
    ) -> None:
        self.timeout = timeout
        #: What pyserial calls the port, for messages.
        self.name = "sim://"
        self.lock = threading.RLock()
        self._data_ready = threading.Condition(self.lock)
        self._received = bytearray()
        self.robot = SimulatedRobot(robot_config, seed=seed, write=self._from_controller)
        self._stopping = threading.Event()
        self._is_open = True
        #: Why the simulation thread ended on its own, if it did.
        self._failure: str | None = None
        self._thread: threading.Thread | None = None

    def start(self, *, realtime: bool = True) -> None:
        """Run the simulation on a daemon thread: in real time, or as fast as possible."""
        if self._thread is not None:
            raise RuntimeError("the simulation is already running")
        self._check_open()
        self._thread = threading.Thread(
            target=self._run, args=(realtime,), name="rovlink-sim", daemon=True
        )
        self._thread.start()

    # -- the pyserial subset -----------------------------------------------------------------

    @property
    def is_open(self) -> bool:
        """Whether the port can be read and written."""
        return self._is_open

    @property
    def in_waiting(self) -> int:
        """Bytes ready to read."""
        with self.lock:
            return len(self._received)

    def write(self, data: bytes) -> int:
        """Send bytes to the controller; any replies are readable when this returns."""
        self._check_open()
        with self.lock:
            self.robot.receive(bytes(data))
        return len(data)

    def read(self, size: int = 1) -> bytes:
        """Wait up to :attr:`timeout` for at least one byte; return up to ``size`` bytes."""
        self._check_open()
        if size <= 0:
            return b""
        deadline = None if self.timeout is None else time.monotonic() + self.timeout
        with self._data_ready:
            while not self._received:
                self._check_open()
                if deadline is None:
                    self._data_ready.wait(_READ_SLICE_S)
                    continue
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return b""
                self._data_ready.wait(min(remaining, _READ_SLICE_S))
            data = bytes(self._received[:size])
            del self._received[:size]
            return data

    def reset_input_buffer(self) -> None:
        """Discard everything not yet read."""
        with self.lock:
            self._received.clear()

    def reset_output_buffer(self) -> None:
        """Nothing to do: writes reach the controller at once."""

    def flush(self) -> None:
        """Nothing to do: writes reach the controller at once."""

    def close(self) -> None:
        """Stop the simulation thread; later reads and writes raise ``SerialException``.

        It waits for :attr:`lock` at most :data:`_CLOSE_LOCK_WAIT_S`: a read interrupted by a
        signal handler holds the lock until the handler returns, and a handler that closes the
        port waits for the close. The port is closed all the same (a read looks at least every
        :data:`_READ_SLICE_S` and raises), and the simulation thread ends on its own.
        """
        if not self._is_open:
            return
        self._stopping.set()
        self._is_open = False
        if not self.lock.acquire(timeout=_CLOSE_LOCK_WAIT_S):
            return
        try:
            self._data_ready.notify_all()
        finally:
            self.lock.release()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join()

    def __enter__(self) -> SimulatedPort:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()

    # -- the simulation ----------------------------------------------------------------------

    @property
    def controller(self) -> Controller:
        """The simulated controller."""
        return self.robot.controller

    @property
    def vehicle(self) -> Vehicle:
        """The simulated vehicle's physics state."""
        return self.robot.vehicle

    def advance(self, seconds: float) -> None:
        """Step the simulation by ``seconds`` of simulated time now (any mode)."""
        with self._data_ready:
            self.robot.advance(seconds)

    def _from_controller(self, data: bytes) -> None:
        # Called by the controller, always with the lock held (from write, advance or _run).
        self._received += data
        overflow = len(self._received) - _MAX_BUFFERED_BYTES
        if overflow > 0:
            del self._received[:overflow]
        self._data_ready.notify_all()

    def _check_open(self) -> None:
        if not self._is_open:
            raise serial.SerialException(self._failure or "the simulated port is closed")

    def _run(self, realtime: bool) -> None:
        try:
            self._simulate(realtime)
        except Exception as error:  # a scheduled action's, or the physics'
            # The port closes as a serial port whose device is gone: before, its thread died
            # and writes were still answered from a frozen robot, which looked alive to a host
            # (no failsafe, no motion) while nothing moved.
            logger.exception("the simulation stopped")
            with self._data_ready:
                self._failure = f"the simulation stopped: {type(error).__name__}: {error}"
                self._is_open = False
                self._data_ready.notify_all()

    def _simulate(self, realtime: bool) -> None:
        schedule = TickSchedule(self.robot.tick_s, time.monotonic(), speed=1.0 if realtime else 0.0)
        step = self.robot.step
        while not self._stopping.is_set():
            count = schedule.due(time.monotonic())
            if count:
                with self.lock:
                    for _ in range(count):
                        step()
            wait_s = schedule.seconds_until_next(time.monotonic())
            if wait_s > 0:
                self._stopping.wait(wait_s)
            else:
                # Let the host's threads run between batches. A real pause, not sleep(0): on
                # Python 3.10 sleep(0) returns without sleeping, so this thread took the lock
                # straight back and a query could wait 100-200 ms for a reply already computed.
                time.sleep(_YIELD_S)


def open_port(
    *,
    seed: int | None = None,
    leak_at_s: float | None = None,
    config: Path | str | None = None,
    realtime: bool = True,
    manual: bool = False,
    timeout: float | None = None,
    preset: str | None = None,
    algorithm: str | None = None,
) -> SimulatedPort:
    """Open a simulated controller as a serial port (see :class:`SimulatedPort`).

    ``leak_at_s`` injects a 100 ms leak pulse at that simulated time; ``config`` is a TOML file
    (controller tables plus ``[vehicle]`` and ``[sensors]``); ``preset`` a vehicle of
    :mod:`rovlink.sim.presets` in place of the file's; ``algorithm`` the controller's checksum
    algorithm in place of the file's ``checksum_algorithm``. ``realtime=False`` runs the
    simulation as fast as the CPU allows; ``manual=True`` runs no thread at all: simulated time
    then moves only through :meth:`SimulatedPort.advance`.
    """
    robot_config = load_sim_config(config) if config is not None else None
    if preset is not None:  # the preset's vehicle, the file's controller and sensors
        from rovlink.sim.presets import preset_config  # noqa: PLC0415

        robot_config = preset_config(preset, robot_config)
    if algorithm is not None:
        base = robot_config or SimConfig()
        robot_config = dataclasses.replace(
            base, controller=dataclasses.replace(base.controller, checksum_algorithm=algorithm)
        )
    port = SimulatedPort(robot_config, seed=seed, timeout=timeout)
    if leak_at_s is not None:
        port.robot.inject_leak(at_s=leak_at_s)
    if not manual:
        port.start(realtime=realtime)
    return port
