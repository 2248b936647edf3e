"""The checks of the conformance suite: each a named function of a :class:`CheckContext`.

A check module declares its checks with :func:`check`; :data:`CHECKS` lists them in the order
they run. A check passes by returning, fails by raising :class:`CheckFailedError` with what was
expected; the runner attaches the exchanges it made as evidence.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from rovlink.conformance.wire import Exchange, Wire
from rovlink.protocol import BadFrame, Command, Frame, Response, encode, get_algorithm

__all__ = [
    "CHECKS",
    "LATE_WAIT_FACTOR",
    "NO_REPLY",
    "Check",
    "CheckAbortedError",
    "CheckContext",
    "CheckFailedError",
    "CheckSkippedError",
    "SuiteOptions",
    "check",
    "checks_markdown",
]


class CheckFailedError(AssertionError):
    """The controller did not behave as the protocol says; the message says what was expected."""


class CheckSkippedError(Exception):
    """The check cannot run here (e.g. motion not allowed); the message says why."""


class CheckAbortedError(Exception):
    """The run must stop at once (a leak, a lost link); ``#stop!`` has been sent."""


#: How a failure words a reply that did not come (the algorithm probe looks for it).
NO_REPLY = "no reply within"
#: What puts the controller back as after a reset, as far as a host can (every check starts so).
_RESTORE = b"#crcoff!#stop!#debug0!#mvdirect.0!"
#: The least time the restore waits for its fence's reply, s; it waits as long as a late reply
#: is watched for (``LATE_WAIT_FACTOR`` reply timeouts) when that is longer.
_RESTORE_WAIT_S = 0.3
#: How long the line must then stay quiet before the next check, s.
_RESTORE_QUIET_S = 0.05
#: After a reply that did not come as expected, the line is watched this many reply timeouts
#: longer for it: a late reply is named, and kept out of the next check.
LATE_WAIT_FACTOR = 3


@dataclass(frozen=True)
class SuiteOptions:
    """How the suite talks to the controller."""

    algorithm: str = "crc8"
    #: How long to wait for a reply before calling it missing, s (the link's latency included).
    reply_timeout_s: float = 0.25
    #: How long the line must stay quiet after a frame that must not be answered, s.
    silence_s: float = 0.12
    #: The reply time the protocol allows (P19), s.
    reply_limit_s: float = 0.005
    #: The serial line's rate, if the link is a serial line (8N1: 10 bits a byte): the time the
    #: query's and the reply's bytes spend on the wire is added to the allowance, as P19 counts
    #: from the query's arrival. None for links without a line rate (TCP, in-process).
    baudrate: int | None = None
    #: Queries timed for the reply-time check.
    timed_queries: int = 40
    #: Whether motion checks may run, and the thrust they use, %.
    motion: bool = False
    motion_percent: int = 30
    #: The controller's link-loss watchdog (P17), s; the failsafe check waits a little longer.
    watchdog_s: float = 2.0
    #: Seed of the random bytes the noise checks send.
    seed: int = 1
    #: How long to wait for a booting controller's first answer, s (P21).
    boot_timeout_s: float = 3.0


@dataclass
class CheckContext:
    """What a check works with: the wire, the options and the exchanges of this check."""

    wire: Wire
    options: SuiteOptions
    exchanges: list[Exchange] = field(default_factory=list)
    #: Whether the check has turned the controller's debug output on (every check starts with
    #: it off). While it is off, what must be answered by no frame is answered by nothing at
    #: all: a dropped frame gets no response, not even a line of text (P4, P5).
    debug_on: bool = False

    # -- frames ------------------------------------------------------------------------------

    def frame(self, command: Command, *, checksum: bool = False) -> bytes:
        """The bytes of ``command``, checksummed with the suite's algorithm if asked."""
        return encode(command, self.options.algorithm if checksum else None)

    def with_checksum(self, body: bytes) -> bytes:
        """``#body`` plus the checksum of ``body`` (for bodies the table would refuse)."""
        return b"#" + body + get_algorithm(self.options.algorithm).digits(body) + b"!"

    # -- exchanges ---------------------------------------------------------------------------

    def ask(self, data: bytes, frames: int = 1) -> Exchange:
        """Send ``data`` and wait for ``frames`` reply frames (and a moment for extra ones)."""
        exchange = self.wire.send(
            data, frames=frames, timeout_s=self.options.reply_timeout_s, linger_s=0.02
        )
        self.exchanges.append(exchange)
        return exchange

    def tell(self, data: bytes) -> Exchange:
        """Send ``data`` that must be answered by no frame, and wait out the silence."""
        exchange = self.wire.send(
            data, frames=0, timeout_s=self.options.silence_s, linger_s=self.options.silence_s
        )
        self.exchanges.append(exchange)
        return exchange

    def settle(self, data: bytes) -> Exchange:
        """Send set-up ``data`` that must be answered by no frame, and wait until the
        controller has taken it: the reply to a ``#qd!`` sent after it as a fence (P20). For
        set-up whose silence is no part of what is checked (the set- checks check that); if
        the fence is not answered, the silence is waited out as :meth:`tell` does."""
        fence = self.frame(Command("qd"), checksum=self.wire.replies_checksummed)
        exchange = self.wire.send(
            data + fence, frames=1, timeout_s=self.options.reply_timeout_s, linger_s=0.02
        )
        self.exchanges.append(exchange)
        if not _answered(exchange, "qd"):
            self.tell(b"")
        return exchange

    def expect_no_frames(self, data: bytes, why: str) -> Exchange:
        """Send ``data``; fail if any frame comes back, or with debug off anything at all: a
        controller writes nothing but replies then (P4, P5), so an ``OK`` or an error line a
        host would skip is a failure too."""
        exchange = self.tell(data)
        if exchange.frames:
            raw = b"".join(frame.raw for frame in exchange.frames)
            raise CheckFailedError(f"{why}, but the controller answered {raw!r}")
        if exchange.received and not self.debug_on:
            raise CheckFailedError(
                f"{why}: with debug off nothing at all (P4, P5), but the controller wrote "
                f"{exchange.received!r}"
            )
        return exchange

    def expect_reply(self, data: bytes, names: tuple[str, ...], why: str = "") -> Exchange:
        """Send ``data``; fail unless exactly the frames ``names`` come back, valid, in order.

        When they do not, the line is watched a while longer: a reply that comes late is
        named in the failure (the controller is slower than the suite waits), and read, so
        that it does not land in the next check's wait as an answer to another query.
        """
        sent_at = self.wire.now_s()
        exchange = self.ask(data, len(names))
        frames = exchange.frames
        got = tuple(_name_of(frame) for frame in frames)
        context = f" ({why})" if why else ""
        if not frames:
            # Text in place of the reply (an error line, a reply spoilt on the line) is named:
            # "no reply" alone reads as a silent line.
            came = f", but text came: {exchange.received!r}" if exchange.received else ""
            raise CheckFailedError(
                f"expected {_names(names)}{context}; {NO_REPLY} "
                f"{self.options.reply_timeout_s * 1000:.0f} ms{came}"
                + self._late(names[0], sent_at)
            )
        for frame in frames:
            if isinstance(frame, BadFrame):
                raise CheckFailedError(
                    f"expected {_names(names)}{context}; got an invalid frame {frame.raw!r}: "
                    f"{frame.detail}"
                )
        if got != names:
            late = self._late(names[0], sent_at) if names[0] not in got else ""
            raise CheckFailedError(f"expected {_names(names)}{context}; got {_names(got)}{late}")
        return exchange

    def _late(self, name: str, sent_at: float) -> str:
        """Watch the line for a late ``$name``; what to add to the failure if it came."""
        options = self.options
        exchange = self.wire.send(
            b"", frames=1, timeout_s=LATE_WAIT_FACTOR * options.reply_timeout_s, linger_s=0.02
        )
        self.exchanges.append(exchange)
        for frame in exchange.valid_frames:
            late = isinstance(frame.message, Response) and frame.message.name == name
            if late and exchange.reply_s is not None:
                late_ms = (self.wire.now_s() - sent_at) * 1000
                return (
                    f"; ${name} came late, about {late_ms:.0f} ms after the query: the controller "
                    f"answers later than the suite waits ({options.reply_timeout_s * 1000:.0f} "
                    "ms, --timeout; P19 allows 5 ms), so its replies land in later queries' waits"
                )
        return ""

    def restore(self, limit_s: float | None = None) -> None:
        """Back to the state after reset as far as a host can: checksum and debug off, locked,
        depth mode; whatever is still arriving is read and discarded.

        A plain ``#qd!`` follows the frames as the fence of P20: what the controller says to
        the frames before it comes before its ``$qd``, however far away the controller is (its
        ``$qd`` is waited for as long as a late reply), and the line is then watched for
        :data:`_RESTORE_QUIET_S` more. (A fixed quiet alone, 100 ms, let the debug lines of a
        controller 150 ms away land in the next check, and cost every check 100 ms.) Without
        that ``$qd`` (a controller that lost its way) the line is watched for twice that quiet.
        ``limit_s``: wait for the ``$qd`` no longer than this (the preflight's boot time).
        """
        wire = self.wire
        wire.replies_checksummed = False  # (#crcoff! acts from the next frame: the fence, P3)
        fence = self.frame(Command("qd"))
        wait_s = max(_RESTORE_WAIT_S, LATE_WAIT_FACTOR * self.options.reply_timeout_s)
        if limit_s is not None:
            wait_s = min(wait_s, max(limit_s, 0.0))
        exchange = wire.send(
            _RESTORE + fence, frames=1, timeout_s=wait_s, linger_s=_RESTORE_QUIET_S
        )
        if not _answered(exchange, "qd"):
            wire.drain(2 * _RESTORE_QUIET_S)


def _answered(exchange: Exchange, name: str) -> bool:
    """Whether a valid ``$name`` reply is among the frames of ``exchange``."""
    return any(
        isinstance(frame.message, Response) and frame.message.name == name
        for frame in exchange.valid_frames
    )


def _name_of(frame: Frame | BadFrame) -> str:
    """A reply's name; ``#name`` for a command frame that came back (a controller that echoes
    what it gets: no reply); ``?`` for an invalid frame."""
    if isinstance(frame, BadFrame):
        return "?"
    return frame.message.name if isinstance(frame.message, Response) else "#" + frame.message.name


def _names(names: tuple[str, ...]) -> str:
    """``$qd $qr`` for reply names; a name that starts with ``#`` (a command frame that came
    back) is shown as the command, ``#qd!``."""
    shown = (f"{name}!" if name.startswith("#") else f"${name}" for name in names)
    return " ".join(shown) or "nothing"


@dataclass(frozen=True)
class Check:
    """One conformance check: a stable name, the rules of PROTOCOL.md it covers, what it does."""

    name: str
    rules: tuple[str, ...]
    description: str
    run: Callable[[CheckContext], None]
    motion: bool = False


#: Every check, in the order they run (the modules register theirs on import).
CHECKS: list[Check] = []


def check(
    name: str, rules: tuple[str, ...], description: str, *, motion: bool = False
) -> Callable[[Callable[[CheckContext], None]], Callable[[CheckContext], None]]:
    """Register the decorated function as a check."""

    def register(function: Callable[[CheckContext], None]) -> Callable[[CheckContext], None]:
        if any(existing.name == name for existing in CHECKS):
            raise ValueError(f"two checks named {name!r}")
        CHECKS.append(Check(name, rules, description, function, motion))
        return function

    return register


def checks_markdown() -> str:
    """Every check as a Markdown table (name, rules, what it shows), as ``docs/builders.md``
    lists them."""
    from rovlink.conformance import runner  # noqa: PLC0415 - registers every module's checks

    lines = ["| check | rules | what it shows |", "|---|---|---|"]
    for item in runner.select_checks(motion=True):
        name = f"`{item.name}`" + (" (`--motion`)" if item.motion else "")
        lines.append(f"| {name} | {' '.join(item.rules)} | {item.description} |")
    return "\n".join(lines) + "\n"
