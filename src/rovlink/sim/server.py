"""The simulated controller on a pseudo-terminal and/or a TCP port (``rovlink sim``).

One thread, one :mod:`selectors` loop: it steps the simulation on its wall-clock schedule, moves
bytes between the peers and the controller, and paces both directions at the line rate when a
baud rate is given. The TCP port takes one client at a time, as a serial port does.

Both links lead to the one controller, but each is its own wire: what the controller writes while
it handles bytes from a link (replies, and debug lines about those frames) goes back on that link
only. What it writes on its own (failsafe and leak lines, from its tick) goes to every link: the
TCP client if one is connected, and the PTY, which cannot tell whether a terminal program has it
open. Output that nobody reads is bounded (the oldest is dropped, as a UART overruns). Input
faster than a paced line carries waits in the kernel once the line holds 4 KB: its writer waits
for room, as on a serial port.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rovlink.controller.lines import SILENT_CLIENT_GIVES_WAY_S, Line, Lines, parse_tcp_address
from rovlink.logs import get_logger
from rovlink.sim.pacing import LinePacer, TickSchedule
from rovlink.sim.robot import SimConfig, SimulatedRobot

__all__ = ["BUSY_MESSAGE", "LINE_BUFFER_BYTES", "SimServer", "parse_tcp_address"]

logger = get_logger(__name__)

#: What a second TCP client reads before it is disconnected.
BUSY_MESSAGE = b"busy: the simulated controller already has a client\r\n"

#: What a paced line holds on its way to the controller before it takes nothing more, bytes: a
#: serial port driver's buffer (a UART's or a USB adapter's, 4 KB on Linux).
LINE_BUFFER_BYTES = 4096

#: The longest the loop sleeps, so a stop request is seen promptly, s.
_MAX_WAIT_S = 0.05


class _Pacers:
    """A line's two directions at the simulated line rate."""

    def __init__(self, baud: int | None) -> None:
        self.to_controller = LinePacer(baud)
        self.from_controller = LinePacer(baud)


class SimServer:
    """One simulated robot served on a PTY and/or TCP, stepped in real time (or faster).

    ``baud`` paces both directions at that rate (8N1); ``None`` leaves the stream unpaced.
    ``speed`` is simulated seconds per wall second, 0 for as fast as the CPU allows. A TCP
    client that has sent nothing for ``silent_client_gives_way_s`` wall seconds (default:
    :data:`~rovlink.controller.lines.SILENT_CLIENT_GIVES_WAY_S`, or the link-loss failsafe's
    time if longer) gives way to a new one, as on a robot, rather than keep it out as busy.
    """

    def __init__(
        self,
        config: SimConfig | None = None,
        *,
        seed: int | None = None,
        baud: int | None = None,
        speed: float = 1.0,
        silent_client_gives_way_s: float | None = None,
    ) -> None:
        self.robot = SimulatedRobot(
            config,
            seed=seed,
            write=self._from_controller,
            write_to_every_line=self._to_every_line,
        )
        self.baud = baud
        self.speed = speed
        if silent_client_gives_way_s is None:
            watchdog_s = self.robot.config.controller.watchdog_s
            watchdog_wall_s = watchdog_s / speed if speed > 0 else 0.0
            silent_client_gives_way_s = max(SILENT_CLIENT_GIVES_WAY_S, watchdog_wall_s)
        self._lines = Lines(
            self._on_bytes,
            busy_message=BUSY_MESSAGE,
            on_open=self._on_open,
            on_close=self._on_close,
            silent_client_gives_way_s=silent_client_gives_way_s,
            finishes_after_hangup=self._has_paced_bytes,
        )
        self._pacers: dict[Line, _Pacers] = {}
        # The line whose bytes the controller is handling: its output goes back there only.
        self._replying_to: Line | None = None

    # -- endpoints ---------------------------------------------------------------------------

    @property
    def pty_path(self) -> str | None:
        """The pseudo-terminal's path, once opened."""
        return self._lines.pty_path

    @property
    def tcp_address(self) -> tuple[str, int] | None:
        """The bound TCP (host, port), once listening."""
        return self._lines.tcp_address

    def open_pty(self) -> str:
        """Open the pseudo-terminal; return the path a terminal program opens."""
        return self._lines.open_pty()

    def listen_tcp(self, host: str = "127.0.0.1", port: int = 0) -> tuple[str, int]:
        """Listen on TCP; return the bound (host, port) (port 0 picks a free one)."""
        return self._lines.listen_tcp(host, port)

    # -- the loop ----------------------------------------------------------------------------

    def serve(self, should_stop: Callable[[], bool]) -> None:
        """Run until ``should_stop()`` is true (checked at least every 50 ms)."""
        robot = self.robot
        schedule = TickSchedule(robot.tick_s, time.monotonic(), speed=self.speed)
        step = robot.step
        while not should_stop():
            now = time.monotonic()
            for _ in range(schedule.due(now)):
                step()
            self._pump()
            wait_s = min(schedule.seconds_until_next(time.monotonic()), self._next_byte_wait_s())
            self._lines.wait(min(wait_s, _MAX_WAIT_S))

    def close(self) -> None:
        """Close every endpoint."""
        self._lines.close()

    # -- bytes -------------------------------------------------------------------------------

    def _on_open(self, line: Line) -> None:
        self._pacers[line] = _Pacers(self.baud)

    def _on_close(self, line: Line) -> None:
        del self._pacers[line]
        self.robot.controller.forget_line(line)

    def _on_bytes(self, line: Line, data: bytes) -> None:
        to_controller = self._pacers[line].to_controller
        to_controller.push(data, time.monotonic())
        self._pump()  # unpaced, the reply leaves in this same turn of the loop
        if len(to_controller) >= LINE_BUFFER_BYTES:
            # A full line takes nothing more: the writer waits for room, as on a serial port,
            # rather than have what it wrote dropped or sent seconds later.
            self._lines.set_reading(line, False)

    def _from_controller(self, data: bytes) -> None:
        now = time.monotonic()
        source = self._replying_to
        if source is not None:
            self._pacers[source].from_controller.push(data, now)
            return
        for pacers in self._pacers.values():  # spontaneous output: a failsafe or leak line
            pacers.from_controller.push(data, now)

    def _to_every_line(self, data: bytes) -> None:
        """What every line must hear, whichever line's bytes the controller is handling (the
        lock changing, another line taking over the driving)."""
        now = time.monotonic()
        for pacers in self._pacers.values():
            pacers.from_controller.push(data, now)

    def _pump(self) -> None:
        """Move every byte whose time has come: to the controller, then to the lines."""
        now = time.monotonic()
        for line, pacers in list(self._pacers.items()):
            data = pacers.to_controller.release(now)
            if data:
                self._replying_to = line
                try:
                    self.robot.receive(data, line)
                finally:
                    self._replying_to = None
                if not line.reading and len(pacers.to_controller) < LINE_BUFFER_BYTES:
                    self._lines.set_reading(line, True)
        for line, pacers in list(self._pacers.items()):
            data = pacers.from_controller.release(now)
            if data:  # anything still unsent waits for the selector to say it is writable
                self._lines.send(line, data)
        for line in [line for line in self._pacers if line.hung_up]:
            if not self._has_paced_bytes(line):  # its last reply is on its way: let it go
                self._lines.finish(line)

    def _has_paced_bytes(self, line: Line) -> bool:
        """Whether bytes of ``line`` are still on their way over the paced line, either way: a
        client that ends its stream gets the replies to what it sent before it is let go."""
        pacers = self._pacers[line]
        return bool(len(pacers.to_controller) or len(pacers.from_controller))

    def _next_byte_wait_s(self) -> float:
        now = time.monotonic()
        wait_s = _MAX_WAIT_S
        for pacers in self._pacers.values():
            for pacer in (pacers.to_controller, pacers.from_controller):
                due = pacer.next_release_s()
                if due is not None:
                    wait_s = min(wait_s, max(due - now, 0.0))
        return wait_s
