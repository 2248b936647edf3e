"""The board loop: the controller on a real board, serving its serial lines.

One thread and one :mod:`selectors` loop. Every control period, at a fixed rate: poll the
sensors, apply the stale-sensor failsafe (to the sensors the controller drives by), run the
board's device checks (a fault found stops and locks the controller), tick the controller
(which sets the thrusters). In between, move bytes between the links and the controller.
Whatever ends the loop (a stop request on SIGTERM or Ctrl-C, an exception anywhere in it), the
``finally`` puts every thruster at neutral before anything else happens.

Replies go back on the link whose bytes the controller is handling; what the controller writes
on its own (failsafe and leak lines) goes to every link. Output nobody reads is bounded.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rovlink.board.board import Board, DeviceCheck
from rovlink.board.schedule import FixedRateSchedule
from rovlink.board.sensors import PolledSensor
from rovlink.board.service_notify import ServiceNotifier
from rovlink.board.watchdog_bounds import board_watchdog_problem
from rovlink.controller import ControllerConfig
from rovlink.controller.controller import Controller
from rovlink.controller.lines import SILENT_CLIENT_GIVES_WAY_S, Line, Lines
from rovlink.logs import get_logger

__all__ = ["BUSY_MESSAGE", "SILENT_CLIENT_GIVES_WAY_S", "BoardServer"]

logger = get_logger(__name__)

#: What a second TCP client reads before it is disconnected.
BUSY_MESSAGE = b"busy: the controller already has a client\r\n"
_MAX_WAIT_S = 0.05  # a stop request is seen at least this often
_SAFE_ATTEMPTS = 3


class BoardServer:
    """The controller on ``board``, served on a serial device, a PTY and/or TCP.

    Raises :class:`ValueError` if ``config`` has the link-loss failsafe off or too long for a
    robot (:mod:`rovlink.board.watchdog_bounds`). A TCP client that has sent nothing for
    ``silent_client_gives_way_s`` (default: :data:`SILENT_CLIENT_GIVES_WAY_S`, or the link-loss
    failsafe's time if longer) gives way to a new one rather than keep it out as busy.
    """

    def __init__(
        self,
        config: ControllerConfig,
        board: Board,
        *,
        overrun_warning_s: float = 10.0,
        service_notifier: ServiceNotifier | None = None,
        silent_client_gives_way_s: float | None = None,
    ) -> None:
        self.board = board
        #: Told after every control period completed (systemd ends a loop that hangs).
        self.service_notifier = service_notifier
        self.clock = board.hardware.clock
        problem = board_watchdog_problem(config.watchdog_s)
        if problem is not None:  # (a board's config refuses it first, naming its file)
            raise ValueError(f"watchdog_s {problem}")
        self.controller = Controller(
            config,
            board.hardware,
            self._from_controller,
            write_to_every_line=self._to_every_line,
        )
        self.schedule = FixedRateSchedule(config.tick_s, self.clock.now_s())
        self._overrun_warning_s = overrun_warning_s
        self._overruns_reported = 0
        self._next_overrun_report_s = 0.0
        self._lines = Lines(
            self._on_bytes,
            busy_message=BUSY_MESSAGE,
            on_close=self._forget_line,
            silent_client_gives_way_s=(
                max(config.watchdog_s, SILENT_CLIENT_GIVES_WAY_S)
                if silent_client_gives_way_s is None
                else silent_client_gives_way_s
            ),
        )
        self._replying_to: Line | None = None
        self._stale: set[str] = set()
        self._unanswered_checks: set[str] = set()
        #: Faults the board's device checks found (a PWM chip reset by a supply dip).
        self.device_faults = 0
        #: Whether the thrusters are known to be at neutral (the board opens them so).
        self.at_rest = True
        #: What the board's probe found after the control loop failed with an I/O error (one
        #: device gone, the whole bus stuck) and what to do; None if it did not.
        self.failure_diagnosis: str | None = None
        self._closing = False

    # -- endpoints ---------------------------------------------------------------------------

    @property
    def pty_path(self) -> str | None:
        """The pseudo-terminal's path, once opened."""
        return self._lines.pty_path

    @property
    def tcp_address(self) -> tuple[str, int] | None:
        """The bound TCP (host, port), once listening."""
        return self._lines.tcp_address

    def open_serial(self, path: str, baud: int) -> None:
        """Serve on a serial device (opened exclusively)."""
        self._lines.open_serial(path, baud)

    def open_pty(self) -> str:
        """Serve on a new pseudo-terminal; its path."""
        return self._lines.open_pty()

    def listen_tcp(self, host: str, port: int) -> tuple[str, int]:
        """Listen on TCP (one client at a time); the bound address."""
        return self._lines.listen_tcp(host, port)

    # -- the loop ----------------------------------------------------------------------------

    def serve(self, should_stop: Callable[[], bool]) -> None:
        """Run until ``should_stop()`` is true; thrusters at neutral however it ends."""
        clock = self.clock
        schedule = self.schedule
        failure: OSError | None = None
        try:
            self.at_rest = False
            schedule.next_s = clock.now_s()
            while not should_stop():
                started_s = clock.now_s()
                if schedule.is_due(started_s):
                    self._control_period(started_s)
                    if schedule.finished(started_s, clock.now_s()):
                        self._report_overruns()
                self._lines.wait(min(schedule.seconds_until_due(clock.now_s()), _MAX_WAIT_S))
        except OSError as error:
            failure = error
            raise
        finally:
            self.make_safe()
            if failure is not None:  # (after neutral: probing a stuck bus takes its time)
                self._diagnose(failure)

    def _diagnose(self, failure: OSError) -> None:
        """Say what the board's I/O ``failure`` means (its bus probed), in the log and in
        :attr:`failure_diagnosis`; never raises (it runs on the way out)."""
        if self.board.diagnose is None:
            return
        try:
            self.failure_diagnosis = self.board.diagnose()
        except Exception:
            logger.exception("probing the board after %s failed", failure)
            return
        logger.error("the control loop failed (%s): %s", failure, self.failure_diagnosis)

    def make_safe(self) -> None:
        """Neutral on every thruster, retried; logged, never raised (it runs in ``finally``)."""
        for attempt in range(1, _SAFE_ATTEMPTS + 1):
            try:
                self.board.make_safe()
            except Exception:  # the bus may be what failed: try again, then say so
                logger.exception("setting the thrusters to neutral failed (attempt %d)", attempt)
                continue
            logger.info("thrusters at neutral")
            self.at_rest = True
            return
        logger.critical("THRUSTERS MAY STILL RUN: neutral could not be set; cut the power")

    def close(self) -> None:
        """Close every line and release the board."""
        self._closing = True
        try:
            self._lines.close()
        finally:
            self.board.close()

    def _forget_line(self, line: Line) -> None:
        """A line has closed: the controller stops what it commanded. While the server closes
        (after :meth:`make_safe`, which says whether neutral was set), a bus that fails that
        stop is logged, so that every line is still closed and the board released."""
        try:
            self.controller.forget_line(line)
        except OSError as error:
            if not self._closing:
                raise
            logger.warning("%s closed: its thrust could not be stopped again: %s", line.name, error)

    # -- one control period ------------------------------------------------------------------

    def _control_period(self, now_s: float) -> None:
        controller = self.controller
        for sensor in self.board.sensors:
            error = sensor.poll(now_s)
            if error is not None and sensor.failures == 1:
                controller.debug(f"{sensor.name}: read failed: {error}")
            if sensor.stale:
                if sensor.name not in self._stale:
                    self._stale.add(sensor.name)
                    self._went_stale(sensor)
                if (
                    sensor.needed_to_drive
                    and not controller.locked
                    and not controller.surfacing_for_leak
                ):
                    controller.failsafe(f"failsafe: {sensor.name} stale ({sensor.failing_text})")
            elif sensor.name in self._stale:
                self._stale.discard(sensor.name)
                controller.debug(f"{sensor.name} answers again")
        # After the sensors: run before, a check's reads would delay an MS5837's convert
        # command, and with it the read a period later.
        for check in self.board.checks:
            if check.is_due(now_s):
                self._check_device(check, now_s)
        controller.tick()
        if self.service_notifier is not None:
            self.service_notifier.pet(now_s)

    def _went_stale(self, sensor: PolledSensor[Any]) -> None:
        """Say that ``sensor`` went stale; one the controller does not drive by is said in a
        debug line too, as no failsafe line tells the pilot."""
        if sensor.needed_to_drive and not self.controller.surfacing_for_leak:
            logger.warning("%s stale: %s", sensor.name, sensor.failing_text)
            return
        if sensor.needed_to_drive:  # (stopped, a leaking robot would stay where it is)
            text = (
                f"{sensor.name} stale ({sensor.failing_text}): surfacing for the leak goes on, "
                "as it needs no depth; the motors stop once a host changes its thrust"
            )
            logger.warning("%s", text)
            self.controller.debug(text)
            return
        text = (
            f"{sensor.name} stale ({sensor.failing_text}): "
            f"{sensor.lost_when_stale}; driving goes on"
        )
        logger.warning("%s", text)
        self.controller.debug(text)

    def _check_device(self, check: DeviceCheck, now_s: float) -> None:
        """Run one device check. A fault is an error in the log and a failsafe: whatever the
        device lost, the robot moves again only when a host starts it again. A check the
        device does not answer is logged once and tried again; it never ends the loop (the
        device's next write, if it fails too, does)."""
        controller = self.controller
        try:
            fault = check.check(now_s)
        except OSError as error:
            if check.name not in self._unanswered_checks:
                self._unanswered_checks.add(check.name)
                logger.warning("%s: check failed: %s", check.name, error)
                controller.debug(f"{check.name}: check failed: {error}")
            return
        if check.name in self._unanswered_checks:
            self._unanswered_checks.discard(check.name)
            logger.info("%s answers its check again", check.name)
        if fault is None:
            return
        self.device_faults += 1
        logger.error("%s", fault)
        if controller.locked:
            controller.debug(fault)
        else:
            controller.failsafe(f"failsafe: {fault}")

    def _report_overruns(self) -> None:
        schedule = self.schedule
        now_s = self.clock.now_s()
        if now_s < self._next_overrun_report_s:
            return
        self._next_overrun_report_s = now_s + self._overrun_warning_s
        new = schedule.overruns - self._overruns_reported
        self._overruns_reported = schedule.overruns
        logger.warning(
            "control loop overran %d time(s) (%d in all, %d periods skipped, longest %.1f ms "
            "for a %.1f ms period)",
            new,
            schedule.overruns,
            schedule.skipped_periods,
            schedule.longest_s * 1000,
            schedule.period_s * 1000,
        )

    # -- bytes -------------------------------------------------------------------------------

    def _from_controller(self, data: bytes) -> None:
        lines = self._lines
        targets = [self._replying_to] if self._replying_to is not None else lines.lines
        for line in list(targets):
            lines.send(line, data)

    def _to_every_line(self, data: bytes) -> None:
        """What every line must hear, whichever line's bytes the controller is handling (the
        lock changing, another line taking over the driving)."""
        lines = self._lines
        for line in list(lines.lines):
            lines.send(line, data)

    def _on_bytes(self, line: Line, data: bytes) -> None:
        self._replying_to = line
        try:
            self.controller.receive(data, line)
        finally:
            self._replying_to = None
