"""Waiting on connect until the controller answers (P21), without I/O.

An Arduino-class board resets when its serial port opens (DTR) and ignores its input for up to
2 s while it boots; a frame sent then is lost. So a client does not send its checksum mode once
and hope: it repeats a *probe* — ``#crcoff!`` (recognised in either mode, P3) and a plain
``#qd!`` — every ``interval_s`` until a ``$qd`` reply arrives or ``boot_timeout`` runs out. Once
one does, it reads on until the line has been quiet for ``quiet_s``, so that the replies to
earlier probes, still on their way, are not taken for the answers to the program's first
queries. After more than one probe no quiet can tell that every probe's reply is in: on a line
slower than the interval, or whose delay varies (a network bridge on a slow or wireless
network), a later probe's reply may follow the first by any time. So the client then sends a
*fence*, a query of another name (``#qr!``), and reads on until its reply, which comes behind
every probe's (P20), then ``quiet_s`` more. Only then does the client put the controller in the
checksum mode asked for.

>>> probe = ReadinessProbe(now=0.0, boot_timeout_s=3.0)
>>> probe.bytes_to_send(0.0)
b'#crcoff!#qd!'
>>> probe.receive(b"$qd.57!", now=0.01)
>>> probe.answered, probe.done(0.05), probe.done(0.2)
(True, False, True)
"""

from __future__ import annotations

import math

from rovlink.client.errors import ConnectError, ConnectionLostError
from rovlink.protocol import Decoder, Event, Frame, Response, Text
from rovlink.protocol.visible import visible

__all__ = ["FENCE_BYTES", "FENCE_PATIENCE_S", "PROBE_BYTES", "ReadinessProbe"]

#: Checksum mode off (either mode recognises it), then a query any controller answers plainly.
PROBE_BYTES = b"#crcoff!#qd!"
#: After more than one probe: a query of another name, answered behind every probe's reply.
FENCE_BYTES = b"#qr!"
#: How long the line must be quiet when the fence's reply never comes (lost to line noise).
FENCE_PATIENCE_S = 1.0


class ReadinessProbe:
    """The state of one readiness wait: when to probe, whether the controller answered."""

    def __init__(
        self, now: float, boot_timeout_s: float, *, interval_s: float = 0.25, quiet_s: float = 0.1
    ) -> None:
        self.boot_timeout_s = boot_timeout_s
        self.deadline = now + boot_timeout_s
        self.interval_s = interval_s
        self.quiet_s = quiet_s
        self.probes_sent = 0
        self.answered = False
        #: Whether the fence's reply came (after more than one probe).
        self.fenced = False
        self._fence_sent_at: float | None = None
        #: The controller's last line of text while it was probed (a boot banner, "busy", …).
        self.last_text: str | None = None
        self._next_probe_at = now
        self._last_data_at = now
        self._decoder = Decoder()

    def bytes_to_send(self, now: float) -> bytes:
        """The probe, if one is due at ``now`` (and the controller has not answered yet);
        once it has, after more than one probe, the fence."""
        if self._fence_due:
            self._fence_sent_at = now
            return FENCE_BYTES
        if self.answered:
            return b""
        if now < self._next_probe_at:
            return b""
        self._next_probe_at = now + self.interval_s
        self.probes_sent += 1
        return PROBE_BYTES

    def receive(self, data: bytes, now: float) -> None:
        """Bytes from the controller: a ``$qd`` reply means it is up; after more than one
        probe, the ``$qr`` reply to the fence means every probe's reply is in."""
        self._last_data_at = now
        if self.fenced or (self.answered and self.probes_sent <= 1):
            return
        self._take(self._decoder.feed(data))

    def lost(self, error: ConnectionLostError) -> ConnectError:
        """``error``, the link lost while probing, as a failure to connect, with what the
        controller said before (a server that refuses a client says why, then closes); a last
        line of text without its line end counts too."""
        self._take(self._decoder.end())
        explained = ConnectError(f"{error}{self.what_it_said}")
        explained.__cause__ = error
        return explained

    def _take(self, events: list[Event]) -> None:
        for event in events:
            if isinstance(event, Text):
                self.last_text = event.text.strip() or self.last_text
            elif isinstance(event, Frame) and isinstance(event.message, Response):
                name = event.message.name
                if not self.answered and name == "qd":
                    self.answered = True
                elif self._fence_sent_at is not None and name == "qr":
                    self.fenced = True
                    return

    @property
    def _fence_due(self) -> bool:
        """Whether the controller answered after more than one probe and the fence is yet to
        be sent."""
        return self.answered and self.probes_sent > 1 and self._fence_sent_at is None

    def _quiet_from(self) -> tuple[float, float]:
        """Since when the line must be quiet, and for how long, before the wait ends: after
        a lone probe's reply (the only one) or the fence's, ``quiet_s``; while the fence's
        reply is missing, :data:`FENCE_PATIENCE_S` since it or the last bytes."""
        if self.probes_sent <= 1 or self.fenced:
            return self._last_data_at, self.quiet_s
        fence_sent_at = self._fence_sent_at if self._fence_sent_at is not None else math.inf
        return max(self._last_data_at, fence_sent_at), FENCE_PATIENCE_S

    def done(self, now: float) -> bool:
        """Whether the controller answered, every probe's reply is in, and the line has been
        quiet since."""
        if not self.answered:
            return False
        since, quiet_s = self._quiet_from()
        return now - since >= quiet_s

    def timed_out(self, now: float) -> bool:
        """Whether ``boot_timeout`` ran out without an answer."""
        return not self.answered and now >= self.deadline

    def wait_s(self, now: float) -> float:
        """How long to wait for bytes before the next step is due."""
        if self.answered:
            if self._fence_due:
                return 0.0
            since, quiet_s = self._quiet_from()
            return max(since + quiet_s - now, 0.0)
        return max(min(self._next_probe_at, self.deadline) - now, 0.0)

    @property
    def what_it_said(self) -> str:
        """``; it said: "…"`` with the controller's last line of text, for an error message;
        empty if it said nothing."""
        if self.last_text is None:
            return ""
        return f'; it said: "{visible(self.last_text)}"'

    def no_answer(self, description: str, *, network: bool) -> ConnectError:
        """The error for a controller that did not answer within ``boot_timeout``; ``network``:
        the link is a network connection (no baud rate to get wrong)."""
        where = "this its address" if network else "this its port and baud rate"
        return ConnectError(
            f"{description}: the controller did not answer within {self.boot_timeout_s:g} s "
            f"({self.probes_sent} probes; is it powered, and is {where}?){self.what_it_said}"
        )
