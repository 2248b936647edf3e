"""The board loop: the controller on a real board, serving its serial lines.

One thread and one :mod:`selectors` loop. Every control period, at a fixed rate: poll the
sensors, apply the stale-sensor failsafe, tick the controller (which sets the thrusters). In
between, move bytes between the links and the controller. Whatever ends the loop (a stop
request on SIGTERM or Ctrl-C, an exception anywhere in it), the ``finally`` puts every thruster
at neutral before anything else happens.

Replies go back on the link whose bytes the controller is handling; what the controller writes
on its own (failsafe and leak lines) goes to every link. Output nobody reads is bounded.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
from collections.abc import Callable

from rovlink.board.board import Board
from rovlink.board.links import Link, PtyLink, SerialLink, TcpLink
from rovlink.board.schedule import FixedRateSchedule
from rovlink.controller import ControllerConfig
from rovlink.controller.controller import Controller
from rovlink.logs import get_logger

__all__ = ["BUSY_MESSAGE", "BoardServer"]

logger = get_logger(__name__)

#: What a second TCP client reads before it is disconnected.
BUSY_MESSAGE = b"busy: the controller already has a client\r\n"
_MAX_PENDING_BYTES = 1 << 16
_MAX_WAIT_S = 0.05  # a stop request is seen at least this often
_SAFE_ATTEMPTS = 3


class BoardServer:
    """The controller on ``board``, served on a serial device, a PTY and/or TCP."""

    def __init__(
        self,
        config: ControllerConfig,
        board: Board,
        *,
        overrun_warning_s: float = 10.0,
    ) -> None:
        self.board = board
        self.clock = board.hardware.clock
        self.controller = Controller(config, board.hardware, self._from_controller)
        self.schedule = FixedRateSchedule(config.tick_s, self.clock.now_s())
        self._overrun_warning_s = overrun_warning_s
        self._overruns_reported = 0
        self._next_overrun_report_s = 0.0
        self._selector = selectors.SelectSelector()
        self._links: list[Link] = []
        self._listener: socket.socket | None = None
        self._tcp_link: TcpLink | None = None
        self._replying_to: Link | None = None
        self._stale: set[str] = set()
        #: Whether the thrusters are known to be at neutral (the board opens them so).
        self.at_rest = True
        self.pty_path: str | None = None
        self.tcp_address: tuple[str, int] | None = None

    # -- endpoints ---------------------------------------------------------------------------

    def open_serial(self, path: str, baud: int) -> None:
        """Serve on a serial device (opened exclusively)."""
        self._add_link(SerialLink(path, baud))

    def open_pty(self) -> str:
        """Serve on a new pseudo-terminal; its path."""
        link = PtyLink()
        self._add_link(link)
        self.pty_path = link.path
        return link.path

    def listen_tcp(self, host: str, port: int) -> tuple[str, int]:
        """Listen on TCP (one client at a time); the bound address."""
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        listener = socket.socket(family, socket.SOCK_STREAM)
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            listener.bind((host, port))
            listener.listen(2)
        except OSError:
            listener.close()
            raise
        listener.setblocking(False)
        self._listener = listener
        self._selector.register(listener, selectors.EVENT_READ, self._on_connection)
        bound = listener.getsockname()
        self.tcp_address = (bound[0], bound[1])
        return self.tcp_address

    # -- the loop ----------------------------------------------------------------------------

    def serve(self, should_stop: Callable[[], bool]) -> None:
        """Run until ``should_stop()`` is true; thrusters at neutral however it ends."""
        clock = self.clock
        schedule = self.schedule
        try:
            self.at_rest = False
            schedule.next_s = clock.now_s()
            while not should_stop():
                started_s = clock.now_s()
                if schedule.is_due(started_s):
                    self._control_period(started_s)
                    if schedule.finished(started_s, clock.now_s()):
                        self._report_overruns()
                wait_s = min(schedule.seconds_until_due(clock.now_s()), _MAX_WAIT_S)
                for key, mask in self._selector.select(wait_s):
                    key.data(key, mask)
        finally:
            self.make_safe()

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
        """Close every link and release the board."""
        for link in list(self._links):
            self._remove_link(link)
        if self._listener is not None:
            self._selector.unregister(self._listener)
            self._listener.close()
            self._listener = None
        self._selector.close()
        self.board.close()

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
                    logger.warning(
                        "%s stale: %d failed reads in a row", sensor.name, sensor.failures
                    )
                if not controller.locked:
                    controller.failsafe(
                        f"failsafe: {sensor.name} stale ({sensor.failures} failed reads in a row)"
                    )
            elif sensor.name in self._stale:
                self._stale.discard(sensor.name)
                controller.debug(f"{sensor.name} answers again")
        controller.tick()

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
        targets = [self._replying_to] if self._replying_to is not None else self._links
        for link in list(targets):
            link.unsent += data
            overflow = len(link.unsent) - _MAX_PENDING_BYTES
            if overflow > 0:  # nobody reads: drop the oldest, as a UART overruns
                del link.unsent[:overflow]
            self._flush(link)

    def _flush(self, link: Link) -> None:
        if link not in self._links:
            return
        try:
            written = link.write(bytes(link.unsent))
        except OSError as error:
            logger.info("%s: write failed (%s), disconnecting", link.name, error)
            self._remove_link(link)
            return
        del link.unsent[:written]
        events = selectors.EVENT_READ | (selectors.EVENT_WRITE if link.unsent else 0)
        self._selector.modify(link.fd, events, self._on_link_event(link))

    def _on_link_event(self, link: Link) -> Callable[[selectors.SelectorKey, int], None]:
        def handle(key: selectors.SelectorKey, mask: int) -> None:
            if mask & selectors.EVENT_READ:
                self._on_readable(link)
            if mask & selectors.EVENT_WRITE and link in self._links:
                self._flush(link)

        return handle

    def _on_readable(self, link: Link) -> None:
        data = link.read()
        if data is None:
            return
        if not data:
            logger.info("%s disconnected", link.name)
            self._remove_link(link)
            return
        self._replying_to = link
        try:
            self.controller.receive(data)
        finally:
            self._replying_to = None

    def _on_connection(self, key: selectors.SelectorKey, mask: int) -> None:
        assert self._listener is not None
        try:
            connection, address = self._listener.accept()
        except BlockingIOError:
            return
        if self._tcp_link is not None:
            logger.info("refused %s:%s: busy", address[0], address[1])
            with contextlib.suppress(OSError):
                connection.setblocking(False)
                connection.send(BUSY_MESSAGE)
            connection.close()
            return
        link = TcpLink(connection)
        self._tcp_link = link
        self._add_link(link)
        logger.info("%s connected", link.name)

    def _add_link(self, link: Link) -> None:
        self._links.append(link)
        self._selector.register(link.fd, selectors.EVENT_READ, self._on_link_event(link))

    def _remove_link(self, link: Link) -> None:
        self._links.remove(link)
        self._selector.unregister(link.fd)
        link.close()
        if link is self._tcp_link:
            self._tcp_link = None
