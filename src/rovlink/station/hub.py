"""One robot link shared by every browser: telemetry, health, the event log, the pilot.

The :class:`Station` owns the tracked asyncio client. It polls the sensors at a steady rate and
sends every browser the reading, the state as last sent, the link's health and who flies; it
runs the relay's watchdog on its own timer, whatever the pages do; and it acts on the messages
the pages send (:mod:`rovlink.station.messages`).

One page at a time is the pilot. Taking control is explicit (``take_control``), is announced
to every page, and cuts the thrust the previous pilot was commanding; only the pilot's input
and commands reach the robot. ``stop`` is honoured from any page: it can only make the robot
safer. Losing the pilot — its WebSocket dropped, its page hidden — zeroes the thrust at once.

A pilot action is a message type in :mod:`rovlink.station.messages` and a branch of
:meth:`Station._act`, refused like the others for a page that is not the pilot: the record
button's start and stop are one (:mod:`rovlink.station.recording`); every page sees the
recording's state and may download the finished ones.

Each page has an outbox that the WebSocket endpoint drains (:mod:`rovlink.station.outbox`): a
page too slow to take its messages skips old readings, heartbeats and recording states (never
queued without bound), never a control change, a log entry or an error; one so far behind
that its outbox is full of those is closed (:meth:`Station.leave`, then it reconnects and gets
a fresh ``hello``).
Every page also gets a ``heartbeat`` each second, whatever the robot's link does, so that a
page can tell a silent station (a network gone quiet without closing the socket) from a slow
robot. A page that sends more messages than any page would (:data:`MESSAGES_PER_S`, after a
burst of :data:`MESSAGE_BURST`) is told to go: :meth:`Station.handle` returns ``False`` and
the WebSocket endpoint closes it.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from rovlink.aio import ClientError
from rovlink.client.events import (
    ClientEvent,
    LinkState,
    MotionExpired,
    QueryFailed,
    ResetSuspected,
    Unsolicited,
)
from rovlink.client.sensors import Sensors
from rovlink.piloting import LockState, SentFrame, TrackedClient
from rovlink.protocol import Command, Text, VerticalMode
from rovlink.protocol.announcements import Announcement, AnnouncementKind
from rovlink.station.limits import command_limits
from rovlink.station.messages import (
    CommandRequest,
    ControlRequest,
    InputMessage,
    MessageError,
    PageMessage,
    RecordRequest,
    StopRequest,
    VisibilityMessage,
    parse_message,
)
from rovlink.station.outbox import Outbox
from rovlink.station.recording import RecordingError, StationRecordings
from rovlink.station.relay import STALE_INPUT_S, ThrustRelay, is_zero_thrust

__all__ = [
    "CLOCK_DRIFT",
    "DEFAULT_RATE_HZ",
    "HEARTBEAT_S",
    "LATE_COMMAND_S",
    "MESSAGES_PER_S",
    "MESSAGE_BURST",
    "TELEMETRY_LOST_S",
    "TELEMETRY_LOST_STATUS",
    "WATCHDOG_PERIOD_S",
    "Peer",
    "Station",
    "telemetry_lost_after",
]

logger = logging.getLogger(__name__)

DEFAULT_RATE_HZ = 10.0
#: How often the relay's watchdog runs: with the 300 ms staleness limit, a stale input is cut
#: within 350 ms, well inside the 500 ms the pilot is promised.
WATCHDOG_PERIOD_S = 0.05
#: The pilot's page re-sends its input this often while the dead-man is held.
INPUT_RESEND_S = 0.05
#: How much chart history a page that opens late is sent.
HISTORY_S = 300.0
#: Event-log entries kept for a page that opens late.
LOG_ENTRIES = 200
#: Messages a page may have waiting; beyond, superseded ones are dropped (see
#: :mod:`rovlink.station.outbox`).
OUTBOX_SIZE = 256
#: Failed polls are logged at most this often (a dead link fails ten a second).
_FAILURE_LOG_EVERY_S = 2.0
#: Every page gets a heartbeat this often, from a task of its own: a page that hears nothing
#: for a few of them knows that what it shows is old (the polls may take longer: a timeout).
HEARTBEAT_S = 1.0
#: A page's messages: this many a second on average, after a burst of :data:`MESSAGE_BURST`
#: (a page polls its input every 10 ms and sends on a change: 100 a second at most; a network
#: that stalled for seconds delivers what it held at once). More closes that page's socket.
MESSAGES_PER_S = 200.0
MESSAGE_BURST = 1000.0
#: A pilot's command that arrives later than this, against the fastest of the page's
#: messages, is not sent: it would act long after it was asked for (a network slower than the
#: page's input delivers everything, each message later than the one before).
LATE_COMMAND_S = 1.0
#: The relay's status while the station closes (:meth:`Station.stop_first`): only STOP is taken.
CLOSING_STATUS = "the station is closing: nothing moves (only STOP is taken)"
#: The relay's state while the robot's link is down: the pilot's input is not taken then, and
#: releasing the dead-man (the relay's own word after a cut) would do nothing.
LINK_DOWN_STATUS = "cut: the robot's link was lost; nothing is relayed until it is back"
#: The controller answered nothing for this long (no reply to a poll, a retry or a keep-alive)
#: while its link is up: it may still hear (a broken TX wire, a reply path that hangs while the
#: motor loop runs), but the pilot no longer sees depth, leak or attitude. The station stops it
#: (``#stop!``): what the controller's own link-loss failsafe (P17, 2 s) does when it hears
#: nothing, the station has it do when the station hears nothing. Four query timeouts of 0.5 s:
#: a reply lost now and then (answered on its retry) never comes near it.
TELEMETRY_LOST_S = 2.0


def telemetry_lost_after(timeout_s: float) -> float:
    """How long a controller may answer nothing before the station stops it, on a link whose
    reply timeout is ``timeout_s``: four timeouts, at least :data:`TELEMETRY_LOST_S` (a slow
    line's longer ``--timeout`` is not taken for a silent controller).

    >>> telemetry_lost_after(0.5), telemetry_lost_after(2.0)
    (2.0, 8.0)
    """
    return max(TELEMETRY_LOST_S, 4 * timeout_s)


#: The relay's state while the controller does not answer: the pilot's input is not taken.
TELEMETRY_LOST_STATUS = (
    "cut: the controller stopped answering (no telemetry): stopped; nothing is relayed"
    " until it answers"
)
#: How far the page's clock may drift from the station's (0.1 %: quartz does far better): a
#: page's input is measured late only beyond it.
CLOCK_DRIFT = 1e-3
#: How many STOPs are remembered by their ``stop_id`` (a page's STOP may arrive twice).
_STOPS_KEPT = 256
#: Why the lock as last sent is no longer known once the robot's link is reopened.
_REOPENED = "the link was reopened (the controller may have reset)"
#: Why "unlocked" as last sent is no longer known once the robot's link is lost.
_LOST = "the link was lost (a controller that stops hearing its line locks)"


@dataclass(eq=False)
class Peer:
    """One connected page: its id, a label people read, and its outbox of messages."""

    id: str
    label: str
    outbox: Outbox = field(default_factory=lambda: Outbox(OUTBOX_SIZE))
    hidden: bool = False
    input_source: str | None = None
    #: The page's message allowance (a token bucket, see :data:`MESSAGES_PER_S`) and when it
    #: was last topped up (``None``: not yet).
    allowance: float = MESSAGE_BURST
    allowance_at_s: float | None = None
    #: The least time any of the page's inputs took to arrive, its clock against the station's
    #: (ms; ``None``: no stamped input yet): an input that took longer waited on the way.
    fastest_arrival_ms: float | None = None
    fastest_at_s: float = 0.0

    def spend(self, now_s: float) -> bool:
        """One message arrived at ``now_s``: whether the page is within its allowance."""
        if self.allowance_at_s is not None:
            earned = (now_s - self.allowance_at_s) * MESSAGES_PER_S
            self.allowance = min(MESSAGE_BURST, self.allowance + max(0.0, earned))
        self.allowance_at_s = now_s
        self.allowance -= 1.0
        return self.allowance >= 0.0

    def lateness_s(self, sent_ms: float, now_s: float) -> float:
        """How much later than the fastest of the page's inputs one sent at ``sent_ms`` (the
        page's clock) arrived at ``now_s`` (the station's): the clocks' offset cancels out.

        The fastest is let drift by :data:`CLOCK_DRIFT` (two computers' clocks do not keep
        quite the same time): a network that holds messages back makes them later much faster.

        >>> peer = Peer("p1", "browser 1")
        >>> peer.lateness_s(1000.0, now_s=50.0), peer.lateness_s(1100.0, now_s=50.7)
        (0.0, 0.599)
        """
        arrival_ms = now_s * 1e3 - sent_ms
        fastest_ms = self.fastest_arrival_ms
        if fastest_ms is not None:
            fastest_ms += max(0.0, now_s - self.fastest_at_s) * 1e3 * CLOCK_DRIFT
        if fastest_ms is None or arrival_ms < fastest_ms:
            fastest_ms = arrival_ms
        self.fastest_arrival_ms, self.fastest_at_s = fastest_ms, now_s
        return round((arrival_ms - fastest_ms) / 1e3, 3)

    @property
    def dropped_messages(self) -> int:
        """Messages the page will never get (superseded ones dropped, or lost with an
        overflow)."""
        return self.outbox.dropped_messages

    def put(self, message: dict[str, Any]) -> None:
        """Queue ``message`` for the page (see :class:`Outbox` for a page too far behind)."""
        self.outbox.put(message)


class Station:
    """The robot link, the relay and the connected pages (see the module's documentation).

    ``description`` names the robot's link on the page. Run :meth:`run` as a task while serving.
    """

    def __init__(
        self,
        tracked: TrackedClient,
        *,
        description: str,
        rate_hz: float = DEFAULT_RATE_HZ,
        clock: Callable[[], float] = time.monotonic,
        recordings: StationRecordings | None = None,
        telemetry_lost_s: float = TELEMETRY_LOST_S,
    ) -> None:
        self.tracked = tracked
        #: The record button's recordings (``None``: the button is off).
        self.recordings = recordings
        self.description = description
        self.rate_hz = rate_hz
        self.relay = ThrustRelay(tracked.commanded)
        self.peers: dict[str, Peer] = {}
        self.pilot: Peer | None = None
        self.latest: Sensors | None = None
        self._clock = clock
        self._started_s = clock()
        self._ids = itertools.count(1)
        self._history: deque[list[float | None]] = deque(maxlen=int(HISTORY_S * rate_hz))
        self._log: deque[dict[str, Any]] = deque(maxlen=LOG_ENTRIES)
        self._failures_unlogged = 0
        self._failure_logged_s = -_FAILURE_LOG_EVERY_S
        self._leak = False
        self._flush_timer: asyncio.TimerHandle | None = None
        self._sending: set[asyncio.Future[None]] = set()
        #: The driver's word on the link (LinkState): down while a lost port is being reopened.
        self._link_up = True
        #: A STOP asked for while the link was down: the reopened link's first frame.
        self._stop_kept = False
        #: After this long without a reply the station stops the robot (:meth:`_check_replies`).
        self.telemetry_lost_s = telemetry_lost_s
        #: The controller stopped answering (and was stopped): nothing is relayed until it
        #: answers again.
        self.telemetry_lost = False
        #: The silence is measured from the last reply, or from this (the station's start, the
        #: link reopened) if later; on :meth:`TrackedClient.now_s`'s clock.
        self._answers_expected_from_s = tracked.now_s()
        self._recording_told_s = 0.0
        #: The station is closing (:meth:`stop_first`): a page may only stop the robot.
        self.closing = False
        #: The latest STOPs done, by their ``stop_id`` (each may arrive twice: see
        #: :meth:`stop_on_its_own`).
        self._stops_done: deque[str] = deque(maxlen=_STOPS_KEPT)
        tracked.client.subscribe(self._on_client_event)
        if recordings is not None:
            tracked.client.subscribe(recordings.on_event)
            recordings.add_failure_listener(self._recording_failed)
        tracked.add_sent_listener(self._on_sent)
        tracked.add_heard_listener(self._on_heard)

    # -- the pages ------------------------------------------------------------------------------

    def join(self, address: str) -> Peer:
        """A page connected from ``address``: it gets its ``hello`` (everything to draw)."""
        number = next(self._ids)
        peer = Peer(id=f"p{number}", label=f"browser {number} ({address})")
        self.peers[peer.id] = peer
        peer.put(self._hello(peer))
        self.log("info", f"{peer.label} connected")
        return peer

    async def leave(self, peer: Peer) -> None:
        """A page's WebSocket closed (or dropped), or is being closed because the page fell
        too far behind (its outbox overflowed): if it was the pilot, thrust goes to zero."""
        if self.peers.pop(peer.id, None) is None:
            return  # left already
        behind = peer.outbox.overflowed
        gone = "fell too far behind (its connection is closed)" if behind else "disconnected"
        if self.pilot is peer:
            self.pilot = None
            await self._cut(f"the pilot's page ({peer.label}) {gone}")
            self._announce_control(f"{peer.label} {gone}; nobody has control")
        self.log("warning" if behind else "info", f"{peer.label} {gone}")

    async def handle(self, peer: Peer, text: str | bytes | None) -> bool:
        """One message from ``peer``; a refused one gets an ``error`` back and sends nothing.

        ``False``: the page sent more messages than any page would (a flood, a runaway
        script), this one is not acted on, and its connection must be closed.
        """
        if not peer.spend(self._clock()):
            self.log(
                "warning",
                f"{peer.label} sent more than {MESSAGES_PER_S:.0f} messages a second: "
                "its connection is closed",
            )
            return False
        try:
            message = parse_message(text)
            await self._act(peer, message)
        except MessageError as error:
            peer.put({"type": "error", "message": str(error)})
        except ClientError as error:
            peer.put({"type": "error", "message": f"the robot's link: {error}"})
            self.log("warning", f"sending failed: {error}")
        except Exception:  # a bug must not take the page's connection down with it
            logger.exception("the station failed on a message from %s", peer.label)
            peer.put({"type": "error", "message": "the station failed on this message (logged)"})
        return True

    # -- running --------------------------------------------------------------------------------

    async def run(self) -> None:
        """Poll the sensors and run the watchdog until cancelled (or until one of them fails,
        which the caller must treat as the end of the station)."""
        tasks = [
            asyncio.ensure_future(self._poll()),
            asyncio.ensure_future(self._watch()),
            asyncio.ensure_future(self._beat()),
        ]
        try:
            await asyncio.gather(*tasks)
        finally:
            for task in tasks:
                task.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def lock_at_start(self) -> None:
        """The station starts by locking the robot (``#stop!``: every output to zero, the motors
        locked), before any page is served. A station killed or crashed mid-dive and started
        again within the controller's link-loss time (P17, 2 s: a service restarted at once, a
        pilot quick on the keys) would otherwise find the robot still moving on the old
        station's last motion, its failsafe fed by the new station's polls for good, while
        every page showed no thrust and the motors as locked after a reset. Locked, the robot
        is what the pages show, as after the failsafe the restart outran."""
        await self.tracked.stop()
        self.log("info", "the station started: #stop! (every output to zero, motors locked)")

    async def stop_first(self) -> None:
        """The station is about to close: thrust to zero and, unless locked as last sent,
        ``#stop!``, now, before the pages' connections are closed (a page whose socket is stuck
        behind full buffers holds their closing up for as long as the server waits for it).
        From then on a page may only stop the robot: nothing unlocks it or flies it again."""
        if self.closing:
            return
        self.closing = True
        self.relay.cut("the station is closing")  # (#stop! zeroes every output: it goes first)
        locked = self.tracked.commanded.sent_lock is LockState.LOCKED
        self.log("warning", f"the station is closing: {'locked' if locked else '#stop!'}")
        await self._stop_unless_locked()
        # The polls stop from now on: without this the pages would keep the last poll's state
        # (unlocked, flying, its thrust) while the robot was stopped.
        self._broadcast(self._telemetry(self.latest))

    async def shutdown(self) -> None:
        """The station is closing: thrust to zero and, unless locked as last sent, ``#stop!``
        (as :meth:`stop_first`, if it was not called); then a running recording is finished
        (its last frame the ``#stop!``)."""
        self.closing = True
        self.relay.cut("the station is closing")
        await self._stop_unless_locked()
        if self.recordings is not None and self.recordings.active:
            finished = await self.recordings.stop()
            logger.info("recording %s finished (%d bytes)", finished.path, finished.size_bytes)

    async def _stop_unless_locked(self) -> None:
        # (As sent by the station itself: a stop heard is no reason to leave without one.)
        if (
            self.tracked.commanded.sent_lock is not LockState.LOCKED
            and not self.tracked.client.closed
        ):
            with contextlib.suppress(ClientError):
                await self.tracked.stop()

    def log(self, level: str, text: str) -> None:
        """Add to the event log every page shows (``info``, ``warning`` or ``alarm``)."""
        entry = {"type": "log", "at_s": round(self.now_s(), 3), "level": level, "text": text}
        self._log.append(entry)
        logger.log(logging.WARNING if level != "info" else logging.INFO, "%s", text)
        self._broadcast(entry)

    def now_s(self) -> float:
        """Seconds since the station started (the pages' time axis)."""
        return self._clock() - self._started_s

    # -- acting on messages ---------------------------------------------------------------------

    async def _act(self, peer: Peer, message: PageMessage) -> None:
        if self.closing and not _is_stop(message):
            raise MessageError("the station is closing: only STOP is taken")
        if isinstance(message, StopRequest):
            await self._stop(peer.label, message.stop_id)
        elif isinstance(message, ControlRequest):
            if message.take and message.from_given:
                self._require_pilot_is(peer, message.from_pilot)
            await (self._take_control(peer) if message.take else self._release_control(peer))
        elif isinstance(message, VisibilityMessage):
            peer.hidden = message.hidden
            if message.hidden and self.pilot is peer:
                await self._cut(f"the pilot's page ({peer.label}) was hidden")
        elif isinstance(message, InputMessage):
            self._require_pilot(peer, "fly")
            if peer.hidden:
                raise MessageError("input from a hidden page is ignored: show the page to fly")
            peer.input_source = message.source
            if message.sent_ms is not None:
                late_s = peer.lateness_s(message.sent_ms, self._clock())
                if late_s > STALE_INPUT_S:
                    # A network slower than the page's input: each message waits longer on the
                    # way, and arriving they keep the relay's input fresh. As old as that, the
                    # input is stale, a release of the dead-man too: cut, relay nothing.
                    if self.relay.armed:
                        await self._cut(
                            f"the page's input arrives {late_s:.1f} s late (a slow network?)"
                        )
                    return
            if not self._link_up or self.telemetry_lost:
                # Nothing can be relayed (or nothing may, flying blind), and the relay, cut
                # when the link was lost or went silent, stays so: armed or "flying" on the
                # page would claim what the robot is not doing.
                return
            depth = self.latest.depth_cm if self.latest is not None else None
            moving, armed = self.relay.moving, self.relay.armed
            await self._send_all(self.relay.update(message.pilot, self._clock(), depth_cm=depth))
            self._log_cut(moving=moving, was_armed=armed)  # a frozen pad is often seen here
            self._schedule_flush()
        elif isinstance(message, CommandRequest):
            if message.command.name == "stop":
                await self._stop(peer.label)
                return
            self._require_pilot(peer, "send commands")
            if self.telemetry_lost and message.command.name == "start":
                raise MessageError(
                    "#start!: not sent: the controller is not answering (no depth, leak or "
                    "attitude to fly by); unlock once it answers again"
                )
            if message.sent_ms is not None:
                late_s = peer.lateness_s(message.sent_ms, self._clock())
                if late_s > LATE_COMMAND_S:
                    # Held up on a network slower than the page's input: sent now, it would act
                    # long after it was asked for, unasked.
                    raise MessageError(
                        f"#{message.command.name}: arrived {late_s:.1f} s late (a slow "
                        "network?): not sent; ask again"
                    )
            try:
                await self.tracked.send(message.command)
            except ClientError as error:
                # Not kept (it would act later, unasked): the pilot is told which command did
                # not go, not only that the link failed.
                self.log("warning", f"{peer.label}: {message.command} not sent: {error}")
                raise MessageError(
                    f"{message.command} not sent: the robot's link: {error}"
                ) from None
            self.log("info", f"{peer.label}: {message.command}")
            dropped_because = self.tracked.commanded.last_dropped_because
            if dropped_because is not None:
                # Sent (the state is what was sent), and the controller drops it: the pilot
                # who pressed the button is told, not only the event log.
                peer.put({"type": "error", "message": f"{message.command}: {dropped_because}"})
        elif isinstance(message, RecordRequest):
            self._require_pilot(peer, "start or stop a recording")
            await self._record(peer, start=message.start)

    async def _record(self, peer: Peer, *, start: bool) -> None:
        recordings = self.recordings
        if recordings is None:
            raise MessageError("this station records nothing (rovlink web --recordings DIR)")
        try:
            if start:
                name = recordings.start(peer.label)
                self.log("info", f"{peer.label} started recording to {name}")
            else:
                finished = await recordings.stop()
                self.log(
                    "info",
                    f"{peer.label} stopped recording: {finished.name}, "
                    f"{finished.size_bytes / 1000:.1f} kB, {finished.duration_s:g} s",
                )
                if finished.failed and recordings.failure is not None:
                    self.log("alarm", recordings.failure)  # it failed as it was being stopped
        except RecordingError as error:
            raise MessageError(str(error)) from None
        self._broadcast(recordings.state())

    def _require_pilot_is(self, peer: Peer, expected_id: str | None) -> None:
        """A page takes control from the pilot it knows of (``None``: nobody): another page
        that took it a moment before is not displaced without the page asking first."""
        pilot = self.pilot
        if pilot is None or pilot is peer or pilot.id == expected_id:
            return
        raise MessageError(
            f"{pilot.label} took control a moment before: nothing changed "
            "(take control again to take it from them)"
        )

    def _require_pilot(self, peer: Peer, what: str) -> None:
        if self.pilot is not peer:
            holder = self.pilot.label if self.pilot is not None else "nobody"
            raise MessageError(
                f"only the pilot may {what}; {holder} has control (take control first)"
            )

    async def stop_on_its_own(self, stop_id: str | None, page_id: str | None, address: str) -> None:
        """A page's STOP on a connection of its own (the ``/stop`` WebSocket): the page's own
        socket may be stuck behind what it has still to send (a network slower than the
        pilot's input), or dead without either end knowing it yet (a Wi-Fi that roamed). The
        same STOP may arrive over both: ``stop_id`` names it, and the second does nothing."""
        peer = self.peers.get(page_id) if page_id is not None else None
        await self._stop(peer.label if peer is not None else f"a page ({address})", stop_id)

    async def _stop(self, label: str, stop_id: str | None = None) -> None:
        if stop_id is not None:
            if stop_id in self._stops_done:
                return  # that press arrived the other way first
            self._stops_done.append(stop_id)
        self.relay.cut(f"STOP from {label}")
        down = not self._link_up
        await self.tracked.stop()  # (never waits: on a link down, the driver keeps it)
        if down:
            # Not sent yet: the driver writes it first on the reopened link (and the
            # controller's own failsafe, P17, stops the robot meanwhile).
            self._stop_kept = True
            self.log(
                "warning",
                f"STOP from {label}: the robot's link is down; #stop! is the first frame"
                " on the reopened link",
            )
        else:
            self.log("warning", f"STOP from {label}")

    async def _take_control(self, peer: Peer) -> None:
        previous = self.pilot
        if previous is peer:
            return
        if previous is not None:
            await self._cut(f"{peer.label} took control from {previous.label}")
        else:
            self.relay.disarm()
        self.pilot = peer
        taken = f" from {previous.label}" if previous is not None else ""
        self._announce_control(f"{peer.label} took control{taken}")

    async def _release_control(self, peer: Peer) -> None:
        if self.pilot is not peer:
            return
        self.pilot = None
        await self._cut(f"{peer.label} released control")
        self._announce_control(f"{peer.label} released control; nobody has control")

    def _announce_control(self, text: str) -> None:
        self.log("info", text)
        self._broadcast({"type": "control", **self._control_state(), "text": text})

    def _control_state(self) -> dict[str, Any]:
        pilot = self.pilot
        return {
            "pilot_id": pilot.id if pilot is not None else None,
            "pilot_label": pilot.label if pilot is not None else None,
        }

    async def _cut(self, reason: str) -> None:
        """Zero thrust now (the relay disarms) and say why.

        A zero the link cannot take (lost, being reopened) is an alarm in the log, not an
        error for the caller: what the cut is part of (a pilot leaving, control changing hands)
        still happens. The relay is disarmed whatever the link does, and the driver zeroes the
        motion first on a reopened link.
        """
        moving = self.relay.moving
        commands = self.relay.cut(reason)
        if self.closing and self.tracked.commanded.lock is LockState.LOCKED:
            # Stopped on the way out (see stop_first): the #stop! stays the last frame.
            commands = []
        try:
            await self._send_all(commands)
        except ClientError as error:
            self.log("alarm", f"zero thrust could not be sent ({reason}): {error}")
            return
        if moving:
            self.log("warning", f"thrust to zero: {reason}")

    def _log_cut(self, *, moving: bool, was_armed: bool) -> None:
        """Say why, when the relay cut (disarmed) since ``was_armed`` and ``moving`` were read."""
        if was_armed and not self.relay.armed:
            reason = self.relay.cut_reason or "stale input"
            self.log("warning", f"{'thrust to zero' if moving else 'disarmed'}: {reason}")

    def _schedule_flush(self) -> None:
        """A change the relay held back (``min_interval_s``) goes out when it is due, not at
        the next watchdog round."""
        due_s = self.relay.due_s
        if due_s is None or self._flush_timer is not None:
            return
        loop = asyncio.get_running_loop()
        self._flush_timer = loop.call_later(max(0.0, due_s - self._clock()), self._flush_due)

    def _flush_due(self) -> None:
        self._flush_timer = None
        due_s = self.relay.due_s
        if due_s is None:
            return  # nothing held any more (sent with a newer input, or cut)
        if due_s > self._clock():
            self._schedule_flush()  # the timer fired early
            return
        task = asyncio.ensure_future(self._send_held())
        self._sending.add(task)
        task.add_done_callback(self._sending.discard)

    async def _send_held(self) -> None:
        """Send the change the relay held back. It is taken from the relay here, not when the
        timer fired, and each frame is checked before it goes: a cut handled in between (the
        pilot left, another page took control) must not be followed by the old motion."""
        try:
            commands = self.relay.flush(self._clock()) if self._may_relay() else []
            for command in commands:
                if not self._may_relay():
                    return
                await self.tracked.send(command)
        except ClientError as error:
            self.log("warning", f"sending failed: {error}")
        self._schedule_flush()  # a newer input held back meanwhile

    def _may_relay(self) -> bool:
        """Whether the pilot's motion may go out now: a pilot, on a shown page, relay armed."""
        pilot = self.pilot
        return (
            pilot is not None and not pilot.hidden and self.relay.armed and not self.telemetry_lost
        )

    async def _send_all(self, commands: list[Command]) -> None:
        for command in commands:
            await self.tracked.send(command)

    # -- the loops ------------------------------------------------------------------------------

    async def _watch(self) -> None:
        """The watchdog: the page's input must stay fresh while the dead-man is held."""
        while True:
            await asyncio.sleep(WATCHDOG_PERIOD_S)
            try:
                await self._check_replies()
            except ClientError as error:
                self.log("alarm", f"#stop! could not be sent: {error}")
            except Exception:  # the watchdog must outlive any bug in what it calls
                logger.exception("the station's watchdog failed once; it goes on")
            try:
                moving, armed = self.relay.moving, self.relay.armed
                commands = self.relay.check(self._clock())  # a cut, or a held change now due
                await self._send_all(commands)
                self._log_cut(moving=moving, was_armed=armed)
            except ClientError as error:
                self.log("alarm", f"zero thrust could not be sent: {error}")
            except Exception:  # the watchdog must outlive any bug in what it calls
                logger.exception("the station's watchdog failed once; it goes on")

    async def _check_replies(self) -> None:
        """The controller must keep answering: one that hears but no longer answers (a broken
        TX wire, a hung reply path) would be flown blind, its depth, leak and attitude on every
        page old while the thrust went on. Silent for :attr:`telemetry_lost_s` on a link that
        is up, it is stopped (``#stop!``: it still hears, and obeys) and the pilot told why;
        nothing is relayed until it answers again, and then it must be unlocked (``#start!``)
        and the dead-man released and pressed."""
        if self.closing or not self._link_up:
            return  # closing: stopped already; the link lost: its own failsafe (P17)
        health = self.tracked.health
        since_s = self._answers_expected_from_s
        if health.last_reply_at_s is not None:
            since_s = max(since_s, health.last_reply_at_s)
        silent_s = self.tracked.now_s() - since_s
        if self.telemetry_lost:
            if silent_s < self.telemetry_lost_s:
                self.telemetry_lost = False
                self.log(
                    "warning",
                    "the controller answers again: unlock (#start!), then release and press"
                    " the dead-man to fly",
                )
            return
        if silent_s < self.telemetry_lost_s:
            return
        self.telemetry_lost = True
        reason = f"the controller stopped answering for {silent_s:.1f} s"
        commands = self.relay.cut(reason)
        locked = self.tracked.commanded.sent_lock is LockState.LOCKED
        self.log(
            "alarm",
            f"{reason}: depth, leak and attitude are not known;"
            f" {'zero thrust (locked)' if locked else '#stop!'}: it may still hear, and it"
            " stops; nothing is relayed until it answers",
        )
        self._broadcast(self._telemetry(self.latest))
        if locked:
            await self._send_all(commands)  # dropped if locked; a lock it missed is covered
        else:
            await self.tracked.stop()  # (#stop! zeroes every output)

    async def _beat(self) -> None:
        """The heartbeat every page gets, whatever the polls do (see :data:`HEARTBEAT_S`)."""
        while True:
            await asyncio.sleep(HEARTBEAT_S)
            self._broadcast({"type": "heartbeat", "t": round(self.now_s(), 3)})

    async def _poll(self) -> None:
        period_s = 1.0 / self.rate_hz
        loop = asyncio.get_running_loop()
        next_s = loop.time()
        while True:
            if self.closing:
                # Stopped on the way out: the #stop! is the last frame the robot gets (and the
                # last of a recording), while the pages' connections are closed.
                await asyncio.sleep(period_s)
                continue
            try:
                reading: Sensors | None = await self.tracked.sensors()
            except ClientError as error:  # a timeout, or the link lost (and being reopened)
                self._poll_failed(str(error))
                reading = None
            try:
                if reading is not None:
                    self._reading(reading)
                else:
                    self._no_reading()
            except Exception:  # the pages miss one reading; the polls (P17's food) go on
                logger.exception("the station failed on a reading")
            now_s = loop.time()
            self._tell_recording(now_s)
            next_s += period_s
            if next_s <= now_s:
                # Late (a slow reply, a busy moment): the next poll a period from now. Going at
                # once put two readings in the same millisecond (one time twice in the charts)
                # and, on a link slower than the rate, left no room between polls for motion.
                next_s = now_s + period_s
            await asyncio.sleep(next_s - loop.time())

    def _tell_recording(self, now_s: float) -> None:
        """Once a second while recording, the pages get its state (its time, a failure)."""
        recordings = self.recordings
        if recordings is None or not recordings.active or now_s < self._recording_told_s + 1.0:
            return
        self._recording_told_s = now_s
        self._broadcast(recordings.state())

    def _recording_failed(self, reason: str) -> None:
        """The recording stopped by itself (a full disk): every page is told at once."""
        self.log("alarm", reason)
        if self.recordings is not None:
            self._broadcast(self.recordings.state())

    def _poll_failed(self, error: str) -> None:
        self._failures_unlogged += 1
        now = self._clock()
        if now - self._failure_logged_s >= _FAILURE_LOG_EVERY_S:
            count = self._failures_unlogged
            more = f" ({count} polls failed since the last note)" if count > 1 else ""
            self.log("warning", f"sensor poll failed: {error}{more}")
            self._failure_logged_s = now
            self._failures_unlogged = 0

    def _no_reading(self) -> None:
        """A poll failed: no reading is current any more (a page opened now shows none, and
        a depth nudge does not start from an old depth); the charts get a gap."""
        self.latest = None
        message = self._telemetry(None)
        commanded = self.tracked.commanded
        self._history.append([message["t"], None, commanded.target_depth_cm, None, None, None])
        self._broadcast(message)

    def _reading(self, reading: Sensors) -> None:
        self.latest = reading
        if reading.leak_detected and not self._leak:
            self.log("alarm", "LEAK: the leak sensor fired (latched until reset)")
        elif self._leak and not reading.leak_detected:
            self.log("info", "leak latch clear")
        self._leak = reading.leak_detected
        message = self._telemetry(reading)
        self._history.append(
            [
                message["t"],
                reading.depth_cm,
                self.tracked.commanded.target_depth_cm,
                reading.roll_deg,
                reading.pitch_deg,
                reading.heading_deg,
            ]
        )
        self._broadcast(message)

    # -- what the pages are sent ----------------------------------------------------------------

    def _telemetry(self, reading: Sensors | None) -> dict[str, Any]:
        commanded = self.tracked.commanded
        relay = self.relay
        return {
            "type": "telemetry",
            "t": round(self.now_s(), 3),
            "sensors": None
            if reading is None
            else {
                "depth_cm": reading.depth_cm,
                "pressure_raw": reading.pressure_raw,
                "leak": reading.leak_detected,
                "roll_deg": reading.roll_deg,
                "pitch_deg": reading.pitch_deg,
                "heading_deg": reading.heading_deg,
            },
            "commanded": {
                "lock": str(commanded.lock),
                "lock_unknown_because": commanded.lock_unknown_because,
                "heard_lock": None if commanded.heard_lock is None else str(commanded.heard_lock),
                "heard_lock_because": commanded.heard_lock_because,
                "vertical_mode": None
                if commanded.vertical_mode is None
                else str(commanded.vertical_mode),
                "target_depth_cm": commanded.target_depth_cm,
                "holding_entry_depth": commanded.holding_entry_depth,
                "vertical_thrust_percent": commanded.vertical_thrust_percent,
                "direction_deg": commanded.direction_deg,
                "power_percent": commanded.power_percent,
            },
            "relay": {
                "armed": relay.armed,
                "moving": relay.moving,
                "status": self._relay_status(),
            },
            "link": self._link_health(),
            **self._control_state(),
            "pilot_input": self.pilot.input_source if self.pilot is not None else None,
        }

    def _relay_status(self) -> str:
        """The relay's state in words for the pages, the station's own state first."""
        if self.closing:
            return CLOSING_STATUS
        if not self._link_up:
            return LINK_DOWN_STATUS
        if self.telemetry_lost:
            return TELEMETRY_LOST_STATUS
        return self.relay.status

    def _link_health(self) -> dict[str, Any]:
        client = self.tracked.client
        health = self.tracked.health
        counters = client.counters
        return {
            "description": self.description,
            "connected": self._link_up and not client.closed,
            "status": health.status,
            "round_trip_ms": None if health.last_reply_s is None else health.last_reply_s * 1e3,
            "average_round_trip_ms": None
            if health.average_reply_s is None
            else health.average_reply_s * 1e3,
            "timeouts": counters.timeouts,
            "retries": counters.retries,
            "checksum_errors": counters.checksum_errors,
            "bad_frames": counters.bad_frames,
            "late_replies": counters.late_replies,
            "resets_suspected": counters.resets_suspected,
            "motion_expiries": counters.motion_expiries,
            "frames_sent": counters.frames_sent,
            "frames_received": counters.frames_received,
            "checksum": client.checksum_enabled,
        }

    def _hello(self, peer: Peer) -> dict[str, Any]:
        return {
            "type": "hello",
            "id": peer.id,
            "label": peer.label,
            "description": self.description,
            "rate_hz": self.rate_hz,
            "heartbeat_ms": HEARTBEAT_S * 1e3,
            "limits": command_limits(),
            "stale_input_ms": STALE_INPUT_S * 1e3,
            "input_resend_ms": INPUT_RESEND_S * 1e3,
            "history": list(self._history),
            "log": list(self._log),
            "telemetry": self._telemetry(self.latest),
            "recording": self.recordings.state() if self.recordings is not None else None,
            **self._control_state(),
        }

    def _broadcast(self, message: dict[str, Any]) -> None:
        for peer in self.peers.values():
            peer.put(message)

    # -- what the driver reports ----------------------------------------------------------------

    def _on_client_event(self, event: ClientEvent) -> None:
        if isinstance(event, ResetSuspected):
            self.log(
                "warning",
                f"the controller may have reset ({event.consecutive_timeouts} timeouts in a row):"
                " it is locked now; start again to fly",
            )
        elif isinstance(event, MotionExpired):
            frames = " ".join(str(command) for command in event.commands)
            self.log("warning", f"the driver expired a motion nobody renewed: {frames}")
        elif isinstance(event, LinkState):
            detail = f": {event.detail}" if event.detail else ""
            if event.state == "lost":
                # Nothing can be sent now; the controller's own failsafe (P17) stops the robot.
                # Disarmed, the relay sends nothing when the link is back until the pilot
                # releases and presses the dead-man again.
                self._link_up = False
                self.relay.cut("the robot's link was lost")
                if self.tracked.commanded.lock is LockState.UNLOCKED:
                    # Its failsafe (P17), or the line that drove going, locks the robot: the
                    # pages must not go on showing its motors unlocked. Locked stays locked.
                    self.tracked.commanded.forget_lock(_LOST)
                self.log("alarm", f"link lost{detail}")
            else:
                self._link_up = True
                # Reopened, the controller's silence is measured from now.
                self._answers_expected_from_s = self.tracked.now_s()
                if event.state == "reconnected":
                    # Input taken while the link was down (the dead-man let go and held again)
                    # does not fly the robot the moment the link is back: release and press
                    # the dead-man on the reopened link.
                    self.relay.cut("the robot's link was reopened")
                    self._reopened()
                    self.log(
                        "warning",
                        f"link reconnected{detail}: the controller may have reset or stopped"
                        " on its own failsafe; unlock (#start!) to fly again",
                    )
                    return
                self.log("info", f"link {event.state}{detail}")
        elif isinstance(event, Unsolicited) and isinstance(event.event, Text):
            self.log("info", f"controller: {event.event.text}")
        elif isinstance(event, QueryFailed):
            pass  # counted in the link health; the poll loop notes failures at a bounded rate

    def _reopened(self) -> None:
        """The robot's link was reopened: what was last sent no longer says what the robot is
        doing. The driver took the motion to rest on it (zero thrust before its readiness probe,
        seen here only as bytes, and again once the controller answered, before this notice);
        the motion as last sent is put at rest here whatever the driver wrote. A reopened serial
        port resets many boards (DTR), and a controller that came back may be another boot, or
        stopped by its failsafe (P17): the lock is no longer known — unless a STOP was asked
        for while the link was down, whose ``#stop!`` the driver wrote first on it: locked."""
        commanded = self.tracked.commanded
        if commanded.power_percent:
            commanded.apply(Command("th", (commanded.direction_deg, 0)), own=False)
        if commanded.vertical_mode is VerticalMode.DIRECT and commanded.vertical_thrust_percent:
            commanded.apply(Command("mvs", (0,)), own=False)
        if self._stop_kept:
            # A STOP while the link was down went first on the reopened link, and the
            # controller answered after it: locked (a controller that reset is locked too).
            self._stop_kept = False
            commanded.apply(Command("stop"), own=False)
            return
        commanded.forget_lock(_REOPENED)

    def _on_heard(self, announcement: Announcement) -> None:
        """The controller announced a lock change (debug output on) that the station did not
        send: every page is told now, not at the next poll. A stop heard cuts the relay as a
        STOP pressed here would (unlocked again, the pilot releases and presses the dead-man);
        its zero thrust is not sent: nothing heard makes the station send anything, and the
        controller has zeroed every output already."""
        commanded = self.tracked.commanded
        if announcement.kind is AnnouncementKind.LOCKED:
            self.relay.cut(f"motors {commanded.lock_text()}")
            self.log("warning", f"motors {commanded.lock_text()}: unlock (#start!) to fly again")
        else:
            self.log("info", f"motors {commanded.lock_text()}; this station flies once unlocked")
        self._broadcast(self._telemetry(self.latest))

    def _on_sent(self, sent: SentFrame) -> None:
        if sent.warning is None or self._zero_to_locked(sent):
            return
        self.log("warning", f"{sent.text}: {sent.warning}")

    def _zero_to_locked(self, sent: SentFrame) -> bool:
        """Zero thrust sent while locked as last sent (a cut after STOP): the controller drops
        it, and it holds zero anyway, so there is nothing to warn about."""
        command = sent.command
        return (
            command is not None
            and is_zero_thrust(command)
            and self.tracked.commanded.lock is LockState.LOCKED
        )


def _is_stop(message: PageMessage) -> bool:
    """Whether ``message`` asks for ``#stop!`` (the STOP message, or the command)."""
    return isinstance(message, StopRequest) or (
        isinstance(message, CommandRequest) and message.command.name == "stop"
    )
