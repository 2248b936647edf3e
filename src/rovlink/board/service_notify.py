"""systemd's service watchdog: the control loop proves it still runs, or systemd ends it.

A controller that hangs (a bug looping for ever, a driver call that never returns) leaves the
PWM board making the last pulses, and nothing in the process can help: its own link-loss
failsafe runs in the same loop. With ``WatchdogSec=`` in the unit, systemd expects a
``WATCHDOG=1`` message at least that often; when they stop it kills the process, and the unit's
``ExecStopPost`` (``--neutral``) sets the thrusters to neutral. The board loop sends the message
after each control period it completes, so a loop that stops completing periods stops it.

The protocol is a datagram to the socket named by ``$NOTIFY_SOCKET`` (``sd_notify(3)``), so no
library is needed. ``READY=1`` is sent once the controller serves (``Type=notify``: systemd
arms the watchdog then, so a slow start is not taken for a hang); ``WATCHDOG=1`` only when
``$WATCHDOG_USEC`` asks for it. Not under systemd, nothing is sent.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Mapping

from rovlink.logs import get_logger

__all__ = ["ServiceNotifier"]

logger = get_logger(__name__)


class ServiceNotifier:
    """``READY=1`` to systemd once the controller serves; ``WATCHDOG=1`` from the control loop
    at half its ``WatchdogSec=`` (as ``sd_watchdog_enabled(3)`` advises), if it has one
    (``interval_s`` None: it has not)."""

    def __init__(self, socket_path: str, interval_s: float | None) -> None:
        # An abstract socket's name is written with a leading "@" in the environment.
        self._address = "\0" + socket_path[1:] if socket_path.startswith("@") else socket_path
        self.interval_s = interval_s
        self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        # Sent from the control loop, which sets the thrusters: a queue systemd does not empty
        # must fail the send (said once), never hold the loop.
        self._socket.setblocking(False)
        self._next_s = float("-inf")
        self._failed = False

    @classmethod
    def from_environment(
        cls, environment: Mapping[str, str] | None = None
    ) -> ServiceNotifier | None:
        """What systemd asks for in ``environment`` (this process's by default): None when not
        under systemd (no ``$NOTIFY_SOCKET``); a watchdog interval when ``$WATCHDOG_USEC`` is
        set for this process (``$WATCHDOG_PID``)."""
        environment = os.environ if environment is None else environment
        path = environment.get("NOTIFY_SOCKET", "")
        if not path:
            return None
        usec = environment.get("WATCHDOG_USEC", "")
        pid = environment.get("WATCHDOG_PID", "")
        watched = usec.isdigit() and int(usec) > 0 and pid in ("", str(os.getpid()))
        return cls(path, int(usec) / 2e6 if watched else None)

    def ready(self) -> None:
        """Tell systemd the controller serves (``Type=notify``)."""
        self._send(b"READY=1")

    def pet(self, now_s: float) -> None:
        """A control period completed at ``now_s``: tell systemd's watchdog if it is time to."""
        if self.interval_s is None or now_s < self._next_s:
            return
        self._next_s = now_s + self.interval_s
        self._send(b"WATCHDOG=1")

    def close(self) -> None:
        """Close the socket."""
        self._socket.close()

    def _send(self, message: bytes) -> None:
        try:
            self._socket.sendto(message, self._address)
        except OSError as error:  # systemd will act on the silence: say why, once
            if not self._failed:
                self._failed = True
                logger.error("cannot notify systemd at %s: %s", self._address, error)
            return
        self._failed = False
