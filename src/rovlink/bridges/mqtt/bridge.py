"""The MQTT bridge: one robot's telemetry, state and events on a broker; commands from it.

QoS and what survives a broker outage:

* ``telemetry``: QoS 0, at most once. Readings taken while the broker is away are dropped;
  ``seq`` shows the gap.
* ``state``: QoS 1, retained, published on every change and every few seconds, and again on
  each reconnect: a subscriber always gets the latest state, never a stale one.
* ``events``: QoS 1, at least once. Events that happen while the broker is away are kept (up
  to 1000) and published, in order, when it is back; beyond that the oldest give way, and an
  ``events_dropped`` event published ahead of the kept ones says how many and when (and so does
  the log).
* ``cmd``: QoS 1 with a clean session: a command published while the bridge is away is not kept
  for later (a late ``th 90 100`` is not what anyone wants); the sender gets no reply.
  Commands are carried out in order, one at a time; a ``stop`` at once, ahead of the rest.
  A command that would move or unlock the robot and reaches the bridge late is refused: older
  than ``max_command_age_s`` by its ``at``, or handed over by a broker that had left a
  publication of the bridge unanswered that long (a broker that stalled, :mod:`command_age`).
* the last will: retained ``{"online": false}`` on ``state`` when the bridge vanishes. A bridge
  that ends on its own says why instead: ``bridge stopped``, ``controller link lost: …`` (after a
  ``link`` event) or ``bridge failed: …``.

Losing the broker zeroes the thrust as last sent (a ``failsafe`` event): no command, not even
``stop``, can reach the robot until it is back.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from typing import Any

from rovlink.aio.wakeup import wait_for_event
from rovlink.bridges.kept_settings import KeptSettings
from rovlink.bridges.mqtt.broker import KEEPALIVE_S, BrokerSettings
from rovlink.bridges.mqtt.broker_failure import broker_failure
from rovlink.bridges.mqtt.command_age import (
    DEFAULT_MAX_COMMAND_AGE_S,
    BrokerSilence,
    publication_age_problem,
)
from rovlink.bridges.mqtt.commands import CommandPolicy
from rovlink.bridges.mqtt.connection import broker_connection
from rovlink.bridges.mqtt.failure_notes import FailureNotes
from rovlink.bridges.mqtt.outbox import DEFAULT_CAPACITY, KeptEvent, Outbox
from rovlink.bridges.mqtt.payloads import (
    CommandRequest,
    PayloadError,
    encode,
    event_payload,
    events_dropped_payload,
    offline_state,
    read_request,
    reply_payload,
    state_payload,
    telemetry_payload,
)
from rovlink.bridges.mqtt.refusals import first_refusal, watch_publications
from rovlink.bridges.mqtt.topics import Topics, response_topic_problem
from rovlink.bridges.sensor_poll import SensorPoller, reopening
from rovlink.bridges.task_ending import cancel_and_wait
from rovlink.client.errors import ConnectionLostError, QueryTimeoutError
from rovlink.client.events import ClientEvent, LinkState, MotionExpired, ResetSuspected
from rovlink.client.sensors import Sensors
from rovlink.logs import get_logger
from rovlink.piloting.commanded import LockState
from rovlink.piloting.tracked import TrackedClient
from rovlink.protocol import Command, Response
from rovlink.protocol.announcements import Announcement

__all__ = ["REPLY_TIMEOUT_S", "BridgeReplacedError", "MqttBridge"]

logger = get_logger("rovlink.bridges.mqtt")

_QOS_TELEMETRY = 0
_QOS_RELIABLE = 1
_RETAINED_REFUSED = (
    "a retained command is not carried out (the broker would give it again on every "
    "reconnection): publish commands without retain, and clear this one with an empty "
    "retained message"
)
_RETAINED_STOP = (
    "published retained: carried out, as stop always is, but publish commands without retain "
    "(clear this one with an empty retained message)"
)
_STOP_KEPT_FOR_THE_LINK = (
    "not sent yet: the controller link is down; #stop! goes out as the reopened link's first "
    "frame (at once if it is open and waiting for the controller's first answer; a link event "
    "says when it is back), and meanwhile the controller's own link-loss watchdog stops the robot"
)
_OVERTAKEN_BY_STOP = "not sent: a stop published after it was carried out first"
#: The retained state is refreshed at least this often (its ``at`` and link silence).
_STATE_REFRESH_S = 2.0
#: Reconnection backoff: first wait, doubled up to the last.
_RECONNECT_FIRST_S = 0.2
_RECONNECT_MAX_S = 5.0
#: Telemetry waiting for the broker beyond this drops its oldest (QoS 0 promises no more).
_TELEMETRY_BACKLOG = 64
#: How long the broker has to answer (CONNACK, SUBACK, PUBACK) before the connection is given up.
REPLY_TIMEOUT_S = 5.0
#: The offline state at the end is given up after this (the last will covers a lost broker).
_FAREWELL_S = 2.0
#: A task still running this long after its cancellation (beyond the time it may take to end) is
#: cancelled again: on Python 3.10 a cancellation can be swallowed (bpo-37658).
_RECANCEL_MARGIN_S = 1.0
#: The longest the bridge's tasks may take to end (recancelled meanwhile) before its final
#: ``#stop!`` goes anyway: aiomqtt waits for the broker's side of a disconnect without a bound.
_END_WAIT_S = 10.0
#: MQTT 5's DISCONNECT reason: another client connected with this one's client id.
_SESSION_TAKEN_OVER = 0x8E
#: A connection that lasted this long resets the reconnection backoff, s.
_STABLE_CONNECTION_S = 10.0
#: Topics whose refused publications are said, each once, per connection.
_REFUSALS_SAID = 20
#: Connections in a row ended this soon that make the bridge say a second one may be running.
_SHORT_LIVED_WARNING = 3


@dataclass(frozen=True, slots=True)
class _Asked:
    """A command from the broker, checked, waiting to be carried out."""

    message: Any
    request: CommandRequest
    command: Command
    warning: str | None
    #: How many stops the bridge had carried out when it came: one more, and a command that could
    #: move the robot is not sent.
    stops_before: int
    #: How long the broker had left a publication of the bridge unanswered when it came, s.
    broker_silent_s: float


class BridgeReplacedError(Exception):
    """Another client connected with this bridge's client id (a second bridge for the robot id)
    and the broker handed it this bridge's session: this one ends rather than take it back."""


class MqttBridge:
    """Bridges the robot behind ``rov`` to the broker as ``rovlink/ROBOT_ID/…``.

    Example::

        async with rovlink.aio.connect("sim://") as client:
            bridge = MqttBridge(TrackedClient(client), BrokerSettings("localhost"), "rov-1")
            await bridge.run()
    """

    def __init__(
        self,
        rov: TrackedClient,
        broker: BrokerSettings,
        robot_id: str,
        *,
        rate_hz: float = 5.0,
        allow_commands: bool = False,
        reply_timeout_s: float = REPLY_TIMEOUT_S,
        max_command_age_s: float = DEFAULT_MAX_COMMAND_AGE_S,
        max_kept_events: int = DEFAULT_CAPACITY,
        wall_clock: Callable[[], float] = time.time,
        simulated: bool = False,
    ) -> None:
        self.rov = rov
        #: The controller is rovlink's simulator, not a robot: the state says so (a bridge
        #: started without its URL would otherwise stand for a real robot on the fleet's view).
        self.simulated = simulated
        self.broker = broker
        self.topics = Topics(robot_id)
        self.robot_id = robot_id
        self.policy = CommandPolicy(allow_commands=allow_commands)
        #: Events waiting for the broker; beyond ``max_kept_events`` the oldest give way.
        self.outbox = Outbox(max_kept_events)
        #: The outbox has dropped events since it was last said (logged once an outage).
        self._dropping = False
        #: How long the broker has to answer a connection, subscription or publication, s.
        self.reply_timeout_s = reply_timeout_s
        #: A command that would move or unlock the robot and is older than this is refused, s.
        self.max_command_age_s = max_command_age_s
        self.broker_silence = BrokerSilence()
        self.connected = asyncio.Event()
        self.sequence = 0
        self._wall_clock = wall_clock
        self._latest: Sensors | None = None
        self._telemetry: asyncio.Queue[bytes] = asyncio.Queue(_TELEMETRY_BACKLOG)
        self._wake_publisher = asyncio.Event()
        self._last_state: dict[str, Any] | None = None
        self._last_state_at_s = 0.0
        #: Why the bridge is ending (the offline state's reason), once it is.
        self._ending: str | None = None
        self._link_lost_reported = False
        #: The controller's link is lost and being reopened (a client with ``reconnect``).
        self._link_down = False
        #: Stops from the broker carried out so far (a stop overtakes what came before it).
        self._stops = 0
        #: The kept event being published (see :meth:`_publish_kept_events`).
        self._event_publish: asyncio.Future[None] | None = None
        self.poller = SensorPoller(rov, self._on_reading, rate_hz=rate_hz)
        #: The settings and vertical mode as last sent: sent again after a suspected reset.
        self.kept = KeptSettings()
        self.kept.follow(rov)
        self._background: set[asyncio.Future[None]] = set()
        #: Topics the broker refused to let this connection publish to (each logged once).
        self._refused_topics: set[str] = set()
        rov.client.subscribe(self._on_client_event)
        rov.add_sent_listener(lambda _sent: self._wake_publisher.set())
        rov.add_heard_listener(self._on_heard)

    async def run(self) -> None:
        """Serve until cancelled (or the controller's connection is lost for good: a link that a
        client with ``reconnect`` reopens is served through, commands refused meanwhile).

        A bridge that takes commands (``allow_commands``) sends the robot ``#stop!`` at the
        start, so that its state is known (locked) before anyone commands it, and as soon as
        it begins to end, before the state is marked offline (and once more when it has). A
        telemetry bridge sends neither: it never moves the robot, and its start or end (a
        service restarted) must not stop the robot another tool is flying. It sends ``#stop!``
        when a ``stop`` is published, as any bridge does."""
        drives = self.policy.allow_commands
        if drives:
            await self.rov.stop()
        poller = asyncio.ensure_future(self.poller.run())
        broker = asyncio.ensure_future(self._stay_connected())
        try:
            done, _ = await asyncio.wait([poller, broker], return_when=asyncio.FIRST_EXCEPTION)
            for task in done:
                task.result()
        except Exception as error:
            self._end_reason(error)  # before the broker task is cancelled: it says this reason
            raise
        finally:
            # The robot first: the goodbye below may wait for a stalled broker (the farewell
            # time, a disconnection's reply), and without a motion timeout it would drive on
            # meanwhile, after Ctrl-C. Stopped again at the very end, in case a command being
            # carried out went out after this.
            if drives:
                with contextlib.suppress(ConnectionError):
                    await self.rov.stop()
            # The broker task says goodbye as it ends (the offline state), within the farewell
            # time and a disconnection's reply: cancelled again only if it runs on beyond that.
            ending = asyncio.ensure_future(
                cancel_and_wait(
                    [poller, broker, *self._background],
                    recancel_after_s=_FAREWELL_S + self.reply_timeout_s + _RECANCEL_MARGIN_S,
                )
            )
            ended, _ = await asyncio.wait([ending], timeout=_END_WAIT_S)
            if not ended:  # (left behind: the process is ending, and the stop must not wait)
                logger.warning(
                    "the bridge's tasks did not end within %g s; stopping the robot anyway",
                    _END_WAIT_S,
                )
            if drives:
                with contextlib.suppress(ConnectionError):
                    await self.rov.stop()

    # -- the broker connection ---------------------------------------------------------------

    async def _stay_connected(self) -> None:
        import aiomqtt  # noqa: PLC0415 - the mqtt extra loads only here

        loop = asyncio.get_running_loop()
        wait_s = _RECONNECT_FIRST_S
        short_lived = 0  # connections in a row that the broker ended soon after they began
        notes = FailureNotes()
        while True:
            connected_at_s: float | None = None
            try:
                async with broker_connection(self._client(aiomqtt)) as mqtt:
                    connected_at_s = loop.time()
                    notes.connected()
                    logger.info("connected to %s", self.broker.describe())
                    try:
                        await self._serve(mqtt)
                    except aiomqtt.MqttError:
                        if _taken_over(mqtt):
                            # Taking it back would take turns with the other for ever, five
                            # times a second, the retained state flipping online and offline.
                            raise BridgeReplacedError(
                                f"another client connected to {self.broker.describe()} as "
                                f"rovlink-bridge-{self.robot_id} and took this bridge's session "
                                f"over: is a second bridge running with --robot "
                                f"{self.robot_id}? Each robot needs its own id"
                            ) from None
                        raise  # the broker is gone: nothing can be said (the last will does)
                    except BaseException as error:
                        # Whatever ends the bridge, the retained state must not stay online:
                        # the clean disconnect that follows discards the last will.
                        await self._say_goodbye(mqtt, self._end_reason(error))
                        raise
            except aiomqtt.MqttError as error:
                self.connected.clear()
                failure = broker_failure(
                    error,
                    self.broker,
                    connected=connected_at_s is not None,
                    reply_timeout_s=self.reply_timeout_s,
                )
                if connected_at_s is not None:
                    await self._zero_thrust(f"broker {self.broker.describe()} {failure}")
                    # The backoff starts again only after a connection that held: one ended at
                    # once, again and again, is no broker restart.
                    if loop.time() - connected_at_s >= _STABLE_CONNECTION_S:
                        wait_s, short_lived = _RECONNECT_FIRST_S, 0
                    else:
                        short_lived += 1
                else:
                    # The broker itself is away (or refusing us): no other bridge is taking
                    # turns with this one, whatever ended the connections before.
                    short_lived = 0
                said = notes.note(failure, loop.time())
                logger.log(
                    logging.DEBUG if said is None else logging.WARNING,
                    "broker %s: %s; retrying in %g s",
                    self.broker.describe(),
                    failure if said is None else said,
                    wait_s,
                )
                if short_lived >= _SHORT_LIVED_WARNING:
                    logger.error(
                        "broker %s ended this bridge's connection %d times in a row soon after "
                        "it began: is a second bridge running with --robot %s? (The broker "
                        "hands the MQTT client id rovlink-bridge-%s to the newest connection, "
                        "and the two take turns.) Each robot needs its own id",
                        self.broker.describe(),
                        short_lived,
                        self.robot_id,
                        self.robot_id,
                    )
                await asyncio.sleep(wait_s)
                wait_s = min(wait_s * 2, _RECONNECT_MAX_S)
            except asyncio.CancelledError:
                self.connected.clear()
                raise

    def _client(self, aiomqtt: Any) -> Any:
        broker = self.broker
        tls_params = None
        if broker.tls:
            tls_params = aiomqtt.TLSParameters(
                ca_certs=None if broker.ca_file is None else str(broker.ca_file),
                certfile=None if broker.cert_file is None else str(broker.cert_file),
                keyfile=None if broker.key_file is None else str(broker.key_file),
            )
        will = aiomqtt.Will(
            self.topics.state,
            encode(offline_state(self.robot_id, "bridge connection lost")),
            qos=_QOS_RELIABLE,
            retain=True,
        )
        client = aiomqtt.Client(
            broker.host,
            broker.port,
            username=broker.username,
            password=broker.password,
            identifier=f"rovlink-bridge-{self.robot_id}",
            protocol=aiomqtt.ProtocolVersion.V5,
            will=will,
            keepalive=KEEPALIVE_S,
            tls_params=tls_params,
            tls_insecure=broker.insecure if broker.tls else None,
            timeout=self.reply_timeout_s,
        )
        watch_publications(client, self._on_publication_refused)
        return client

    def _access_control(self) -> str:
        user = self.broker.username
        return f"user {user!r}" if user else "anonymous clients"

    def _on_publication_refused(self, topic: str, reason: str) -> None:
        if topic in self._refused_topics or len(self._refused_topics) >= _REFUSALS_SAID:
            return  # (an asker naming new response topics without end is not said without end)
        self._refused_topics.add(topic)
        own = (self.topics.telemetry, self.topics.state, self.topics.events)
        if topic in (*own, self.topics.command_reply):
            logger.error(
                "broker %s refused this bridge's publication to %s (%s): nobody receives it; "
                "check the broker's access control for %s",
                self.broker.describe(),
                topic,
                reason,
                self._access_control(),
            )
        else:  # a response topic its asker chose
            logger.warning(
                "broker %s refused this bridge's reply to the response topic %s (%s): its asker "
                "gets no reply; the broker's access control for %s does not allow it",
                self.broker.describe(),
                topic,
                reason,
                self._access_control(),
            )

    async def _serve(self, mqtt: Any) -> None:
        if self._event_publish is not None:
            self._event_publish.cancel()  # on the connection before: that event is sent again
        from paho.mqtt.subscribeoptions import SubscribeOptions  # noqa: PLC0415

        # No retained command (MQTT 5's retain handling 2): the broker would hand it over on
        # every (re)connection, a `th 90 100` published minutes or a broker restart ago. And a
        # live one keeps its flag (retain as published), to be refused: carried out once, it
        # would stay stored on the broker for the next connection of a bridge without this.
        granted = await mqtt.subscribe(
            self.topics.command,
            options=SubscribeOptions(
                qos=_QOS_RELIABLE,
                retainAsPublished=True,
                retainHandling=SubscribeOptions.RETAIN_DO_NOT_SEND,
            ),
        )
        refusal = first_refusal(granted)
        if refusal is not None:  # (the bridge serves on: telemetry, state, events)
            logger.error(
                "broker %s refused this bridge's subscription to %s (%s): no command, not even "
                "stop, reaches the robot through the broker; check the broker's access control "
                "for %s",
                self.broker.describe(),
                self.topics.command,
                refusal,
                self._access_control(),
            )
        self._refused_topics.clear()  # (said again on each connection: the rules may change)
        self._last_state = None  # publish it afresh: the broker may have restarted
        self.connected.set()
        queue: asyncio.Queue[_Asked] = asyncio.Queue()
        tasks = [
            asyncio.ensure_future(self._receive(mqtt, queue)),
            asyncio.ensure_future(self._carry_out_in_order(mqtt, queue)),
            asyncio.ensure_future(self._publish(mqtt)),
        ]
        try:
            done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
            for task in done:
                task.result()  # the broker went away (MqttError), or a fault
        finally:
            self.connected.clear()
            await cancel_and_wait(tasks, recancel_after_s=_RECANCEL_MARGIN_S)
            # Readings the lost connection did not carry (a stalled broker held the publisher
            # back) are dropped, not published on the next one seconds late: QoS 0 telemetry is
            # live, and its seq shows the gap.
            while not self._telemetry.empty():
                self._telemetry.get_nowait()

    async def _receive(self, mqtt: Any, queue: asyncio.Queue[_Asked]) -> None:
        """Commands in the order they came, one at a time (a query waits for its reply), but a
        ``stop`` at once: it must not wait for a query the controller does not answer. What came
        before it and is not yet sent is not to unlock or move the robot after it: those
        commands are dropped (answered so); the others (settings, queries) follow in order."""
        async for message in mqtt.messages:
            asked = await self._read_command(mqtt, message)
            if asked is None:
                continue
            if asked.command.name != "stop":
                queue.put_nowait(asked)
                continue
            self._stops += 1
            waiting = [queue.get_nowait() for _ in range(queue.qsize())]
            for kept in waiting:
                if not kept.command.spec.moves_or_unlocks:
                    queue.put_nowait(kept)
            await self._carry_out(mqtt, asked)
            for overtaken in waiting:
                if overtaken.command.spec.moves_or_unlocks:
                    await self._answer(mqtt, overtaken, error=_OVERTAKEN_BY_STOP)

    async def _carry_out_in_order(self, mqtt: Any, queue: asyncio.Queue[_Asked]) -> None:
        while True:
            await self._carry_out(mqtt, await queue.get())

    async def _publish(self, mqtt: Any) -> None:
        loop = asyncio.get_running_loop()
        while True:
            await self._publish_state(mqtt, loop.time())
            await self._publish_kept_events(mqtt)
            while not self._telemetry.empty():
                await mqtt.publish(self.topics.telemetry, self._telemetry.get_nowait(), qos=0)
            self._wake_publisher.clear()
            await wait_for_event(self._wake_publisher, _STATE_REFRESH_S / 2)

    async def _publish_state(self, mqtt: Any, now_s: float) -> None:
        state = state_payload(
            self.robot_id,
            self.rov.commanded,
            self.rov.health,
            depth_cm=None if self._latest is None else self._latest.depth_cm,
            leak=None if self._latest is None else self._latest.leak_detected,
            commands_allowed=self.policy.allow_commands,
            simulated=self.simulated,
            at_s=self._wall_clock(),
            now_s=self.rov.now_s(),
        )
        if self._link_down:
            state["link"]["status"] = "lost"  # (being reopened)
        comparable = {k: v for k, v in state.items() if k not in ("at", "link")}
        comparable["link_status"] = state["link"]["status"]
        if comparable == self._last_state and now_s - self._last_state_at_s < _STATE_REFRESH_S:
            return
        await self._publish_reliably(mqtt, self.topics.state, encode(state), retain=True)
        self._last_state = comparable
        self._last_state_at_s = now_s

    async def _publish_kept_events(self, mqtt: Any) -> None:
        """Publish the kept events, oldest first, after saying how many were dropped if the
        outbox was full. Each publish goes on when its caller is cancelled, so that the goodbye
        that follows waits for it rather than sending it twice."""
        while True:
            self._say_drops()
            kept = self.outbox.peek()
            if kept is None:
                return
            publish = self._event_publish
            if publish is None or publish.done():
                publish = asyncio.ensure_future(self._publish_event(mqtt, kept))
                self._event_publish = publish
            await asyncio.shield(publish)

    async def _publish_event(self, mqtt: Any, event: KeptEvent) -> None:
        await self._publish_reliably(mqtt, event.topic, event.payload)
        self.outbox.done(event)

    def _say_drops(self) -> None:
        """The events the full outbox dropped, said in the log and in an ``events_dropped``
        event ahead of the kept ones (the dropped ones came before them)."""
        drops = self.outbox.take_drops()
        if drops is None:
            return
        self._dropping = False
        at_s = self._wall_clock()
        payload = events_dropped_payload(self.robot_id, drops, self.outbox.capacity, at_s)
        logger.warning("broker %s: %s", self.broker.describe(), payload["detail"])
        self.outbox.put_first(self.topics.events, encode(payload), at_s)

    async def _publish_reliably(self, mqtt: Any, topic: str, payload: bytes, **kwargs: Any) -> None:
        """Publish at QoS 1, timing the broker's answer (a stalled broker's silence)."""
        with self.broker_silence.awaiting_answer():
            await mqtt.publish(topic, payload, qos=_QOS_RELIABLE, **kwargs)

    async def _say_goodbye(self, mqtt: Any, reason: str) -> None:
        """Publish the kept events (the last may say why), then the retained offline state,
        within :data:`_FAREWELL_S` (the broker may be slow or gone: the last will covers that)."""
        offline = encode(offline_state(self.robot_id, reason))

        async def goodbye() -> None:
            await self._publish_kept_events(mqtt)
            await self._publish_reliably(mqtt, self.topics.state, offline, retain=True)

        try:
            await asyncio.wait_for(goodbye(), _FAREWELL_S)
        except Exception as error:  # ending anyway; the last will may say it
            logger.warning(
                "could not publish the offline state: %s", str(error) or type(error).__name__
            )

    def _end_reason(self, error: BaseException) -> str:
        """Why the bridge ends, for the offline state: the first reason given is kept (the
        error that ended one task is followed by the cancellation of the other)."""
        if self._ending is None:
            if isinstance(error, asyncio.CancelledError):
                self._ending = "bridge stopped"
            elif isinstance(error, ConnectionLostError):
                self._ending = f"controller link lost: {error}"
                if not self._link_lost_reported:  # the driver says so only when it reconnects
                    self._event("link", f"lost {error}")
            else:
                self._ending = f"bridge failed: {type(error).__name__}: {error}"
        return self._ending

    # -- commands ------------------------------------------------------------------------------

    async def _read_command(self, mqtt: Any, message: Any) -> _Asked | None:
        """The command a message asks for, if it may be carried out; else the reply saying why
        is sent (``None``)."""
        request: CommandRequest | None = None
        payload = message.payload if isinstance(message.payload, bytes) else b""
        retained = bool(getattr(message, "retain", False))
        if retained and not payload:
            return None  # a retained command being cleared (an empty retained message): not one
        warnings = []
        try:
            request = read_request(payload)
            command = self.policy.check(request.text)
            # Stop can only make the robot safer (P3): carried out however it came.
            if request.problem is not None:
                if command.name != "stop":
                    raise PayloadError(request.problem)
                warnings.append(f"{request.problem}: carried out, as stop always is")
            if retained:
                if command.name != "stop":
                    raise PayloadError(_RETAINED_REFUSED)
                warnings.append(_RETAINED_STOP)
        except (PayloadError, ValueError) as error:
            await self._reply(
                mqtt, message, reply_payload(self.robot_id, request, error=str(error))
            )
            return None
        warning = "; ".join(warnings) or None
        silent_s = self.broker_silence.silent_s()
        return _Asked(message, request, command, warning, self._stops, silent_s)

    async def _carry_out(self, mqtt: Any, asked: _Asked) -> None:
        """Send the command asked for and answer with what became of it."""
        command, warning = asked.command, asked.warning
        if command.name == "stop":
            if self._link_down:
                # The driver keeps it to be the reopened link's first frame: it is not written,
                # so the asker is not told it was (as "ok" would say).
                await self.rov.send(command)
                await self._answer(mqtt, asked, error=_STOP_KEPT_FOR_THE_LINK)
                return
        else:
            await self._restore_settings()  # (after a reset: before what may build on them)
            if (
                command.spec.moves_or_unlocks and asked.stops_before != self._stops
            ):  # a stop came since
                await self._answer(mqtt, asked, error=_OVERTAKEN_BY_STOP)
                return
            late = self._late_because(asked)
            if late is not None:
                await self._answer(mqtt, asked, error=late)
                return
        try:
            replies = await self.rov.send(command)
        except QueryTimeoutError as error:
            await self._answer(mqtt, asked, frame=str(command), error=str(error))
        except ConnectionError as error:
            if not reopening(self.rov, error):
                raise  # the controller is gone for good: the bridge ends
            await self._answer(
                mqtt, asked, error=f"not sent: the controller link is down ({error})"
            )
        else:
            warning = warning or self._dropped_because(command)
            await self._answer(mqtt, asked, frame=str(command), replies=replies, warning=warning)

    def _late_because(self, asked: _Asked) -> str | None:
        """Why a command that would move or unlock the robot comes too late to be carried out
        (:mod:`command_age`); ``None`` if it does not, or moves nothing."""
        if not asked.command.spec.moves_or_unlocks:
            return None
        limit_s = self.max_command_age_s
        if asked.request.published_at_s is not None:
            problem = publication_age_problem(
                asked.request.published_at_s, self._wall_clock(), limit_s
            )
            if problem is not None:
                return problem
        if asked.broker_silent_s > limit_s:
            return (
                f"the broker had answered nothing for {asked.broker_silent_s:.1f} s when it "
                f"handed this over: it may be that old, and motion older than {limit_s:g} s is "
                "not carried out; publish it again"
            )
        return None

    async def _answer(
        self,
        mqtt: Any,
        asked: _Asked,
        *,
        frame: str | None = None,
        replies: tuple[Response, ...] = (),
        error: str | None = None,
        warning: str | None = None,
    ) -> None:
        answer = reply_payload(
            self.robot_id,
            asked.request,
            frame=frame,
            replies=replies,
            error=error,
            warning=warning or asked.warning,
        )
        await self._reply(mqtt, asked.message, answer)

    def _dropped_because(self, command: Command) -> str | None:
        """Why the controller drops ``command`` just sent (locked, the other vertical mode), as
        far as the state as last sent tells; ``None`` if it acts on it."""
        commanded = self.rov.commanded
        if command.spec.is_query or commanded.last_command != command:
            return None
        return commanded.last_dropped_because

    async def _reply(self, mqtt: Any, message: Any, answer: dict[str, Any]) -> None:
        from paho.mqtt.packettypes import PacketTypes  # noqa: PLC0415
        from paho.mqtt.properties import Properties  # noqa: PLC0415

        topic = self.topics.command_reply
        properties = None
        asked = getattr(message, "properties", None)
        response_topic = getattr(asked, "ResponseTopic", None)
        if isinstance(response_topic, str) and response_topic:
            problem = response_topic_problem(response_topic)
            if problem is not None:
                # Whoever asked chose it; publishing would raise and end the bridge, or (a
                # bridge's command topic) have the reply carried out as a command.
                logger.warning(
                    "command %r: no reply sent: its response topic %r %s",
                    answer.get("command"),
                    response_topic,
                    problem,
                )
                return
            topic = response_topic
            correlation = getattr(asked, "CorrelationData", None)
            if correlation is not None:
                properties = Properties(PacketTypes.PUBLISH)  # type: ignore[no-untyped-call]
                properties.CorrelationData = correlation
        await self._publish_reliably(mqtt, topic, encode(answer), properties=properties)

    # -- what the robot does -------------------------------------------------------------------

    def _on_reading(self, sensors: Sensors) -> None:
        previous = self._latest
        self._latest = sensors
        if sensors.leak_detected and (previous is None or not previous.leak_detected):
            self._event("leak", "the leak sensor fired")
        if self.kept.pending:  # the controller answers again after a suspected reset
            self._in_background(self._restore_settings())
        self.sequence += 1
        if self.connected.is_set():
            payload = encode(
                telemetry_payload(self.robot_id, sensors, self.sequence, self._wall_clock())
            )
            if self._telemetry.full():  # (the oldest gives way: a reading is worth its news)
                self._telemetry.get_nowait()
            self._telemetry.put_nowait(payload)
        self._wake_publisher.set()

    def _on_client_event(self, event: ClientEvent) -> None:
        if isinstance(event, MotionExpired):
            frames = " ".join(str(command) for command in event.commands)
            self._event("failsafe", f"motion not renewed: zero thrust sent ({frames})")
        elif isinstance(event, ResetSuspected):
            self.kept.reset_suspected()
            detail = (
                f"{event.consecutive_timeouts} queries timed out: the controller may have reset "
                "(it is locked after a reset)"
            )
            if self.policy.allow_commands and self.rov.commanded.lock is not LockState.LOCKED:
                # The state says the lock as last sent: #stop! makes it say what a reset did
                # (P21), rather than "unlocked" for a robot that no longer moves (or unknown:
                # the suspicion has made the lock as last sent unknown already). A telemetry
                # bridge sends none: a suspicion is no proof, and another tool may be flying.
                self._in_background(self._stop_quietly())
                detail += "; #stop! sent"
            self._event("reset_suspected", detail)
        elif isinstance(event, LinkState):
            lost = event.state == "lost"
            if lost and self.rov.commanded.sent_lock is LockState.UNLOCKED:
                # The robot's own watchdog stops it (P17) unless the link is soon back: #stop!
                # is then the reopened link's first frame, and the state says locked.
                self._in_background(self._stop_quietly())
            if event.state == "reconnected":  # a board the reopened port may have reset (DTR)
                self.kept.reset_suspected()
            self._link_lost_reported = self._link_down = lost
            self._event("link", f"{event.state} {event.detail}".strip())

    def _on_heard(self, _announcement: Announcement) -> None:
        """The controller announced a lock change the bridge did not send (debug output on):
        a ``lock`` event, and the state published now. Nothing is sent to the controller."""
        self._event("lock", f"motors {self.rov.commanded.lock_text()}")
        self._wake_publisher.set()

    def _in_background(self, work: Coroutine[Any, Any, None]) -> None:
        task = asyncio.ensure_future(work)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    async def _zero_thrust(self, reason: str) -> None:
        """Zero the thrust as last sent, if any: with the broker gone no command, not even a
        stop, can reach the robot, and a ``--motion-timeout`` of 0 would let it drive on for as
        long as the broker is away. The lock and a depth held stay, as the motion timeout's."""
        commanded = self.rov.commanded
        commands = []
        if commanded.power_percent:
            commands.append(Command("th", (commanded.direction_deg, 0)))
        if commanded.vertical_thrust_percent:
            commands.append(Command("mvs", (0,)))
        if not commands:
            return
        try:
            for command in commands:
                await self.rov.send(command)
        except ConnectionError as error:
            if not reopening(self.rov, error):
                raise
            return  # (the reopened link's first frame is #stop!: the controller link's loss)
        frames = " ".join(str(command) for command in commands)
        self._event("failsafe", f"{reason}: zero thrust sent ({frames})")

    async def _stop_quietly(self) -> None:
        with contextlib.suppress(ConnectionError):
            await self.rov.stop()

    async def _restore_settings(self) -> None:
        """After a suspected reset, the settings and the vertical mode as last sent, sent again:
        the controller came back with its configured defaults, in depth mode (P21, P9)."""
        frames = await self.kept.restore_in_background(self.rov)
        if frames:
            self._event("reset_suspected", f"the controller answers again: sent again {frames}")

    def _event(self, name: str, detail: str) -> None:
        logger.info("event %s: %s", name, detail)
        at_s = self._wall_clock()
        payload = event_payload(self.robot_id, name, detail, at_s)
        if self.outbox.put(self.topics.events, encode(payload), at_s) and not self._dropping:
            self._dropping = True
            logger.warning(
                "broker %s has not taken the last %d events: the oldest now give way (how many "
                "is published when it takes them again)",
                self.broker.describe(),
                self.outbox.capacity,
            )
        self._wake_publisher.set()


def _taken_over(mqtt: Any) -> bool:
    """Whether the broker ended ``mqtt``'s connection because another client took its session
    (aiomqtt keeps the broker's DISCONNECT reason in its ``_disconnected`` future)."""
    disconnected = getattr(mqtt, "_disconnected", None)
    if not isinstance(disconnected, asyncio.Future) or not disconnected.done():
        return False
    if disconnected.cancelled() or disconnected.exception() is None:
        return False
    reason = getattr(disconnected.exception(), "rc", None)
    return getattr(reason, "value", reason) == _SESSION_TAKEN_OVER
