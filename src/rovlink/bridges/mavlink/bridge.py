"""The MAVLink bridge: a ground station's messages in, the robot's telemetry out, one event loop.

It starts the robot locked in MANUAL (``#stop!``, ``#mvdirect.1!``), serves until cancelled and
leaves the robot locked (``#stop!``) whatever ends it.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import time
from collections.abc import Callable, Coroutine, Iterable
from typing import Any

from rovlink.bridges.kept_settings import KeptSettings
from rovlink.bridges.mavlink import file_transfer
from rovlink.bridges.mavlink.command_handling import (
    Result,
    handle_command,
    mode_result,
)
from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint
from rovlink.bridges.mavlink.failsafe import GcsWatchdog
from rovlink.bridges.mavlink.modes import ButtonFunction, FlightMode
from rovlink.bridges.mavlink.parameters import PILOT_SYSTEM, ParameterError, ParameterTable
from rovlink.bridges.mavlink.pilot_input import PilotInput, all_buttons
from rovlink.bridges.mavlink.rc_override import CHANNEL_OF_AXIS, RcOverride
from rovlink.bridges.mavlink.telemetry_messages import READING_MESSAGES, TelemetryMessages
from rovlink.bridges.mavlink.telemetry_schedule import MAX_RATE_HZ, TelemetrySchedule
from rovlink.bridges.mavlink.vehicle_state import VehicleState
from rovlink.bridges.sensor_poll import SensorPoller, reopening
from rovlink.client.errors import QueryTimeoutError
from rovlink.client.events import ClientEvent, LinkState, ResetSuspected
from rovlink.client.sensors import Sensors
from rovlink.logs import get_logger
from rovlink.piloting.commanded import LockState
from rovlink.piloting.tracked import SentFrame, TrackedClient
from rovlink.protocol import Command
from rovlink.protocol.announcements import Announcement, AnnouncementKind

__all__ = ["LEAK_REPEAT_S", "MavlinkBridge"]

#: The frames that lock or unlock the motors.
_LOCK_COMMANDS = frozenset({"start", "stop"})
logger = get_logger("rovlink.bridges.mavlink")

#: How often "Leak detected" is said while the leak latch is set, s (ArduSub's period).
LEAK_REPEAT_S = 20.0
#: How often the failsafes are checked and due telemetry is sent, s.
_TICK_S = 0.02
#: The sensors are read at least this often, whatever the ground station asks (leak, depth).
_MIN_POLL_HZ = 2.0
_GCS_TYPE = 6  # MAV_TYPE_GCS
_SEVERITY_CRITICAL = 2
_SEVERITY_WARNING = 4
_SEVERITY_INFO = 6
_PARAM_TYPE_INT32 = 6
#: SET_POSITION_TARGET_GLOBAL_INT: the altitude ignored (POSITION_TARGET_TYPEMASK_Z_IGNORE), and
#: the frames whose altitude is above the surface (MAV_FRAME_GLOBAL_INT, _RELATIVE_ALT_INT): the
#: robot has no position, so either's zero is the surface, as its depth sensor's is.
_POSITION_TARGET_Z_IGNORE = 4
_DEPTH_TARGET_FRAMES = frozenset({5, 6})
_MISSION_ACCEPTED = 0  # MAV_MISSION_RESULT
_MISSION_UNSUPPORTED = 3
_MISSION_INVALID_SEQUENCE = 13
#: SET_MODE is acknowledged with its message id as the command, as ArduPilot does (ArduSub's
#: pymavlink example waits for that COMMAND_ACK).
_SET_MODE_MESSAGE_ID = 11
#: An axis held at neutral after arming until centred (said once per axis and arming).
_STICK_HELD = "Joystick {axis} held: return to centre"
_CHANNEL_HELD = "RC {channel} held: return to neutral"
#: A button a new pilot holds at the hand-over: not a press (said once per button).
_BUTTON_HELD = "Button {button} held: release it to use it"
#: ArduSub's pre-arm check, word for word (ground stations show PreArm texts as such).
_NO_DISARM_BUTTON = "PreArm: Must assign a disarm or arm_toggle button"


class MavlinkBridge:
    """Serves the robot behind ``rov`` as a MAVLink vehicle on ``endpoint``.

    Example::

        async with rovlink.aio.connect("sim://") as client:
            bridge = MavlinkBridge(TrackedClient(client), MavlinkEndpoint("udpout:127.0.0.1:14550"))
            await bridge.run()
    """

    def __init__(
        self,
        rov: TrackedClient,
        endpoint: MavlinkEndpoint,
        parameters: ParameterTable | None = None,
        *,
        send_on_start: Iterable[str] = (),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.rov = rov
        self.endpoint = endpoint
        self.parameters = parameters or ParameterTable()
        self.state = VehicleState()
        self.pilot = PilotInput(self.parameters)
        self.rc_override = RcOverride(self.pilot.stale_after_s)
        self.watchdog = GcsWatchdog()
        self._clock = clock
        self._send_on_start = tuple(send_on_start)
        self.schedule = TelemetrySchedule(clock())
        self.messages = TelemetryMessages(endpoint, self.state, rov, self.parameters, clock)
        self.poller = SensorPoller(
            rov, self._on_reading, rate_hz=self._poll_rate_hz(), on_missed=self.state.missed
        )
        self._inbox: asyncio.Queue[Any] = asyncio.Queue()
        #: Systems whose joystick was ignored (not SYSID_MYGCS), each said once.
        self._ignored_pilots: set[int] = set()
        #: Systems whose joystick was aimed at system 0 (every vehicle), each said once.
        self._broadcast_joysticks: set[int] = set()
        #: The leak is said again this often while the latch is set, as ArduSub does: a ground
        #: station that connects later sees a CRITICAL vehicle, and is told why.
        self.leak_repeat_s = LEAK_REPEAT_S
        self._leak_said_at_s: float | None = None
        #: Why the last depth target was ignored, said once until one is taken or why changes.
        self._depth_target_refusal: str | None = None
        self._background: set[asyncio.Future[None]] = set()
        self._handlers: dict[str, Callable[[Any], Any]] = {
            "HEARTBEAT": self._on_heartbeat,
            "MANUAL_CONTROL": self._on_manual_control,
            "RC_CHANNELS_OVERRIDE": self._on_rc_channels_override,
            "COMMAND_LONG": self._on_command_long,
            "COMMAND_INT": self._on_command_int,
            "SET_MODE": self._on_set_mode,
            "PARAM_REQUEST_LIST": self._on_param_request_list,
            "PARAM_REQUEST_READ": self._on_param_request_read,
            "PARAM_SET": self._on_param_set,
            "REQUEST_DATA_STREAM": self._on_request_data_stream,
            "MISSION_REQUEST_LIST": self._on_mission_request_list,
            "MISSION_COUNT": self._on_mission_upload,
            "MISSION_CLEAR_ALL": self._on_mission_clear_all,
            "MISSION_REQUEST_INT": self._on_mission_item_request,
            "MISSION_REQUEST": self._on_mission_item_request,
            "TIMESYNC": self._on_timesync,
            "FILE_TRANSFER_PROTOCOL": self._on_file_transfer,
            "SET_POSITION_TARGET_GLOBAL_INT": self._on_position_target,
        }
        #: The gains, calibration and mode as last sent: sent again after a suspected reset.
        self.kept = KeptSettings()
        self.kept.follow(rov)
        rov.client.subscribe(self._on_client_event)
        rov.add_sent_listener(self._on_sent)
        rov.add_heard_listener(self._on_heard)
        #: The lock as last sent or heard, kept past a suspected reset (which forgets it before
        #: the bridge hears of the reset): whether the vehicle was armed when it happened.
        self._lock_known = rov.commanded.lock

    @property
    def armed(self) -> bool:
        """Unlocked, as last sent, on a link that is open (while it is reopened, the ``#stop!``
        sent on losing it waits to be its first frame)."""
        return self.messages.armed

    async def run(self) -> None:
        """Serve until cancelled or the connection to the controller is lost for good; then
        ``#stop!``. A link that a client with ``reconnect`` reopens is served through: the
        vehicle is disarmed while it is down, and commands meanwhile are refused for now."""
        loop = asyncio.get_running_loop()
        serving = False
        try:
            await self.rov.stop()
            await self.rov.send(Command("mvdirect", (1,)))  # MANUAL, as ArduSub starts
            for command in self.parameters.commands(self._send_on_start):
                await self.rov.send(command)
            self.endpoint.start(self._inbox.put_nowait, loop)
            serving = True
            tasks = [
                asyncio.ensure_future(self.poller.run()),
                asyncio.ensure_future(self._receive()),
                asyncio.ensure_future(self._tick()),
            ]
            try:
                done, _ = await asyncio.wait(tasks, return_when=asyncio.FIRST_EXCEPTION)
                for task in done:
                    task.result()  # a lost connection ends the bridge with its error
            finally:
                for task in tasks:
                    task.cancel()
                await asyncio.gather(*tasks, return_exceptions=True)
        finally:
            stop_sent = True
            try:
                await self.rov.stop()
            except ConnectionError:
                stop_sent = False
            if serving:
                self._say_goodbye(stop_sent)
            self.endpoint.close()

    def _say_goodbye(self, stop_sent: bool) -> None:
        """The ground stations' last messages: why the vehicle goes silent, and a HEARTBEAT
        disarmed and powering off (else one shows the last armed state until it notices the
        silence, seconds later)."""
        try:
            if stop_sent:
                self._say(_SEVERITY_WARNING, "Bridge stopped: motors locked (#stop! sent)")
            else:
                self._say(_SEVERITY_CRITICAL, "Bridge stopped: #stop! could not be sent")
            self.messages.heartbeat(powering_off=True)
        except OSError as error:  # (a ground station's socket gone already: nothing to tell)
            logger.debug("the ground stations could not be told the bridge stopped: %s", error)

    # -- the vehicle's actions (command_handling.VehicleActions) ---------------------------------

    async def arm(self) -> Result:
        """``#start!``; in ALT_HOLD the depth of the moment is held.

        Refused (FAILED) when no joystick button disarms (``BTNn_FUNCTION`` 4 or 2), as in
        ArduSub; while the controller's queries fail, as HEARTBEAT shows it CRITICAL,
        and when it does not answer a query of its own (a pre-arm check, as ArduSub's): a
        controller that has just gone silent fails a poll only a reply timeout or more later.
        An armed vehicle's ARM is accepted at once and changes nothing, as ArduSub's: no
        pre-arm query holds up the messages after it (a disarm) while the robot may move, and
        the depth held in ALT_HOLD stays the one set.
        """
        if self.armed:
            self.watchdog.heartbeat(self._clock())  # (contact all the same)
            return Result.ACCEPTED
        if not self.parameters.disarm_button_assigned():
            self._say(_SEVERITY_CRITICAL, _NO_DISARM_BUTTON)
            return Result.FAILED
        depth_cm = await self._depth_now_cm() if self.messages.link_ok() else None
        if depth_cm is None:
            self._say(_SEVERITY_WARNING, "Arm refused: the controller does not answer")
            return Result.FAILED
        await self._restore_settings()  # (after a reset: not armed before the settings are in)
        self.pilot.hold_off_centre_axes()  # (an override set while disarmed must not drive)
        await self.rov.send(Command("start"))
        self.watchdog.heartbeat(self._clock())  # arming counts as contact
        await self._hold_current_depth(depth_cm)
        self._say(_SEVERITY_INFO, "Armed")
        return Result.ACCEPTED

    async def _depth_now_cm(self) -> int | None:
        """The depth the controller answers now (``None``: no reply within the link's reply
        timeout and retries, as any query: a slow link's ``--timeout`` holds for it too)."""
        try:
            (reply,) = await self.rov.send(Command("qd"))
        except QueryTimeoutError:
            return None
        return reply.values[0]

    async def disarm(self, reason: str) -> Result:
        """``#stop!``, always (while the controller link is being reopened, the driver keeps it
        to be the reopened link's first frame: the STATUSTEXT says so, not that it was sent)."""
        await self.rov.stop()
        logger.warning("stopped: %s", reason)
        if self.messages.link_up:
            self._say(_SEVERITY_INFO, f"Disarmed: {reason}")
        else:
            self._say(_SEVERITY_WARNING, "Disarmed; link down: #stop! sent when it is back")
        return Result.ACCEPTED

    async def set_mode(self, mode: FlightMode) -> Result:
        """MANUAL: ``#mvdirect.1!``; ALT_HOLD: ``#mvdirect.0!`` holding the current depth.

        The mode in force asked again (a ground station's retry, a depth-hold button pressed in
        depth hold) keeps the depth held, as ArduSub: the stick may have moved it since.
        """
        entering = mode is not self.state.mode
        await self.rov.send(Command("mvdirect", (int(mode is FlightMode.MANUAL),)))
        self.state.mode = mode  # (once sent: a link being reopened refuses it)
        if entering and mode is FlightMode.ALT_HOLD and self.armed:
            # The controller holds the depth of this moment itself (P9). The stick moves the
            # hold from the depth a fresh qd answers, asked aside: waited for here, it would
            # hold up the messages after it (a disarm) while the robot may move; and the last
            # poll's depth is up to a poll period old, which sent a diving robot back up.
            self._in_background(self._hold_depth_of_now())
        return Result.ACCEPTED

    async def _hold_depth_of_now(self) -> None:
        """ALT_HOLD just entered, armed: hold the depth a fresh ``qd`` answers (the last poll's
        if it gets none), unless a depth was held meanwhile (a re-arm) or the mode or the lock
        changed."""
        with contextlib.suppress(ConnectionError):  # (a link being reopened: disarmed)
            depth_cm = await self._depth_now_cm()
            if depth_cm is None:
                depth_cm = self.state.depth_cm
            if depth_cm is not None and self.pilot.target_depth_cm is None:
                await self._hold_current_depth(depth_cm)

    async def gripper(self, *, close: bool) -> Result:
        """``#h-!`` (close) or ``#h+!`` (open): only when armed (the claw is motion, P7)."""
        if not self.armed:
            self._say(_SEVERITY_WARNING, "Gripper refused: arm first")
            return Result.DENIED
        await self.rov.send(Command("h-" if close else "h+"))
        return Result.ACCEPTED

    def request_message(self, message_id: int) -> Result:
        """Send one message now, if the bridge has it (DENIED if not; TEMPORARILY_REJECTED for
        one that carries readings while they are not current)."""
        name = self._message_name(message_id)
        if name in READING_MESSAGES and not self.messages.readings_current():
            return Result.TEMPORARILY_REJECTED
        if name is None or not self.messages.send(name):
            return Result.DENIED
        return Result.ACCEPTED

    def set_message_interval(self, message_id: int, interval_us: float) -> Result:
        """SET_MESSAGE_INTERVAL: −1 off, 0 the default, else every ``interval_us`` µs."""
        name = self._message_name(message_id)
        if name is None:
            return Result.DENIED
        if interval_us < 0:
            interval_s: float | None = 0.0
        elif interval_us == 0:
            interval_s = None
        else:
            interval_s = interval_us / 1e6
        if not self.schedule.set_interval(name, interval_s, self._clock()):
            return Result.DENIED  # (HEARTBEAT stays at 1 Hz; a message not sent on a schedule)
        self.poller.set_rate(self._poll_rate_hz())
        return Result.ACCEPTED

    def get_message_interval(self, message_id: int) -> Result:
        """GET_MESSAGE_INTERVAL: MESSAGE_INTERVAL says it (0: not sent on a schedule)."""
        name = self._message_name(message_id)
        interval_us = 0 if name is None else self.schedule.interval_us(name)
        self.messages.message_interval(message_id, interval_us)
        return Result.ACCEPTED

    # -- loops -----------------------------------------------------------------------------------

    async def _receive(self) -> None:
        while True:
            message = await self._inbox.get()
            if not self.endpoint.is_for_me(message):
                self._said_broadcast_joystick(message)
                continue  # for another vehicle, or another component of this one
            handler = self._handlers.get(message.get_type())
            if handler is None:
                continue
            try:
                await handler(message)
            except ConnectionError as error:
                if not reopening(self.rov, error):
                    raise  # the controller is gone for good: the bridge ends
                logger.debug("%s not carried out: %s", message.get_type(), error)
            except Exception:
                # One odd message must not end the bridge (and with it the ground station's
                # control): log it and serve the next.
                logger.exception(
                    "%s from system %s not handled", message.get_type(), message.get_srcSystem()
                )

    async def _tick(self) -> None:
        while True:
            now_s = self._clock()
            if self.watchdog.tripped(now_s, armed=self.armed):
                pilot = self.parameters.pilot_system
                await self.disarm(f"no heartbeat from ground station {pilot} for 3 s")
                self._say(_SEVERITY_CRITICAL, f"Failsafe: GCS {pilot} heartbeat lost, stopped")
            expired = self.pilot.expire(now_s)
            try:
                for command in expired:
                    await self.rov.send(command)
            except ConnectionError as error:
                if not reopening(self.rov, error):
                    raise
                # The reopened link's first frames are zero thrust (the driver's own).
            if expired:
                self._say(_SEVERITY_WARNING, "Failsafe: pilot input stale, thrust zeroed")
            for name in self.schedule.due(now_s):
                if name in READING_MESSAGES and not self.messages.readings_current():
                    continue  # (HEARTBEAT CRITICAL and SYS_STATUS say why)
                try:
                    self.messages.send(name)
                except OSError as error:  # a ground station's socket gone: the next will do
                    logger.debug("%s not sent: %s", name, error)
            await asyncio.sleep(_TICK_S)

    # -- received messages ------------------------------------------------------------------------

    async def _on_heartbeat(self, message: Any) -> None:
        # Only the pilot's ground station (SYSID_MYGCS), as ArduSub: a second one watching
        # must not keep the vehicle armed after the pilot's has gone.
        if message.type == _GCS_TYPE and message.get_srcSystem() == self.parameters.pilot_system:
            self.watchdog.heartbeat(self._clock())

    def _said_broadcast_joystick(self, message: Any) -> None:
        """A joystick aimed at every vehicle (``target`` 0: a script that never read the
        vehicle's id from its HEARTBEAT) drives none, as in ArduSub; said once per ground
        station, as nothing else would tell its pilot why nothing moves."""
        if message.get_type() != "MANUAL_CONTROL" or message.target != 0:
            return
        source = message.get_srcSystem()
        if source not in self._broadcast_joysticks:
            self._broadcast_joysticks.add(source)
            self._say(
                _SEVERITY_WARNING,
                f"Joystick to system 0 ignored: aim it at {self.endpoint.system_id}",
            )

    def _from_pilot(self, message: Any) -> bool:
        """Whether pilot input comes from the pilot's ground station (``SYSID_MYGCS``); if so,
        it is contact for the failsafe, as a heartbeat is (as in ArduSub, whose pymavlink
        examples fly with no heartbeat)."""
        source = message.get_srcSystem()
        if source == self.parameters.pilot_system:
            self.watchdog.heartbeat(self._clock())
            return True
        # Two joysticks would take turns at the thrust, message by message (as ArduSub, only
        # SYSID_MYGCS flies); said once per ground station, so that its pilot knows.
        if source not in self._ignored_pilots:
            self._ignored_pilots.add(source)
            self._say(
                _SEVERITY_WARNING,
                f"Joystick of GCS {source} ignored: SYSID_MYGCS is {self.parameters.pilot_system}",
            )
        return False

    async def _on_manual_control(self, message: Any) -> None:
        if not self._from_pilot(message):
            return
        buttons = all_buttons(message.buttons, getattr(message, "buttons2", 0))  # (MAVLink 1: none)
        await self._fly(message.x, message.y, message.z, buttons, held_text=_STICK_HELD)

    async def _on_rc_channels_override(self, message: Any) -> None:
        if not self._from_pilot(message):
            return
        channels = [getattr(message, f"chan{n}_raw") for n in range(1, 9)]
        x, y, z = self.rc_override.update(channels, self._clock())
        await self._fly(x, y, z, None, held_text=_CHANNEL_HELD)

    async def _fly(self, x: int, y: int, z: int, buttons: int | None, *, held_text: str) -> None:
        """The pilot's stick (and buttons, ``None``: none in this input) to the robot;
        ``held_text`` says an axis is held since arming (``{axis}``, ``{channel}``: its name)."""
        output = self.pilot.manual_control(
            x, y, z, buttons, mode=self.state.mode, armed=self.armed, now_s=self._clock()
        )
        for axis in output.newly_held:
            text = held_text.format(axis=axis, channel=CHANNEL_OF_AXIS[axis])
            self._say(_SEVERITY_WARNING, text)
        for button in output.held_buttons:
            self._say(_SEVERITY_WARNING, _BUTTON_HELD.format(button=button))
        for command in output.commands:
            await self.rov.send(command)
        for function in output.pressed:
            await self._button(function)

    async def _button(self, function: ButtonFunction) -> None:
        if function is ButtonFunction.ARM or (
            function is ButtonFunction.ARM_TOGGLE and not self.armed
        ):
            await self.arm()
        elif function in (ButtonFunction.DISARM, ButtonFunction.ARM_TOGGLE):
            await self.disarm("disarm button")
        elif function is ButtonFunction.MODE_MANUAL:
            await self.set_mode(FlightMode.MANUAL)
        elif function is ButtonFunction.MODE_DEPTH_HOLD:
            await self.set_mode(FlightMode.ALT_HOLD)

    async def _on_command_long(self, message: Any) -> None:
        params = [getattr(message, f"param{n}") for n in range(1, 8)]
        await self._command(message, message.command, params)

    async def _on_command_int(self, message: Any) -> None:
        params = [message.param1, message.param2, message.param3, message.param4]
        params += [float(message.x), float(message.y), message.z]
        await self._command(message, message.command, params)

    async def _command(self, message: Any, command: int, params: list[float]) -> None:
        result = await self._while_link_down(handle_command(self, command, params))
        self._ack(message, command, result)

    async def _on_set_mode(self, message: Any) -> None:
        result = await self._while_link_down(
            mode_result(self, message.base_mode, message.custom_mode)
        )
        self._ack(message, _SET_MODE_MESSAGE_ID, result)

    async def _while_link_down(self, action: Coroutine[Any, Any, Result]) -> Result:
        """``action``'s result; TEMPORARILY_REJECTED if the controller link is being reopened
        (MAVLink's "valid, but not now: retry later"), with a STATUSTEXT."""
        try:
            return await action
        except ConnectionError as error:
            if not reopening(self.rov, error):
                raise
            self._say(_SEVERITY_WARNING, "Not now: the controller link is down")
            return Result.TEMPORARILY_REJECTED

    def _ack(self, message: Any, command: int, result: Result) -> None:
        self.endpoint.mav.command_ack_send(
            command, int(result), 0, 0, message.get_srcSystem(), message.get_srcComponent()
        )

    async def _on_param_request_list(self, message: Any) -> None:
        for name, _ in self.parameters.items():
            self._param_value(name)

    async def _on_param_request_read(self, message: Any) -> None:
        names = self.parameters.names()
        if message.param_index >= 0:
            if message.param_index < len(names):
                self._param_value(names[message.param_index])
            return
        name = _param_name(message.param_id)
        if name in names:
            self._param_value(name)

    async def _on_param_set(self, message: Any) -> None:
        name = _param_name(message.param_id)
        before = self.parameters.value(name) if name in self.parameters.names() else None
        try:
            command = self.parameters.set(name, message.param_value)
        except ParameterError as error:
            self._say(_SEVERITY_WARNING, str(error))
            if name in self.parameters.names():
                self._param_value(name)  # the value in force: the set did not take
            return
        if command is not None:
            try:
                await self.rov.send(command)
            except ConnectionError as error:
                if not reopening(self.rov, error) or before is None:
                    raise
                self.parameters.set(name, before)  # not sent: the value in force stays
                self._say(_SEVERITY_WARNING, f"{name} not set: the controller link is down")
                self._param_value(name)
                return
        if name == PILOT_SYSTEM:
            self._ignored_pilots.clear()  # (a joystick still ignored is said again)
            if self.parameters.value(name) != before:
                # The new pilot's stick or overrides, off centre all along, must not drive at
                # once: held until centred, as at arming; its held buttons are not presses.
                self.pilot.new_pilot()
                self.rc_override.release()
        self._param_value(name)

    def _param_value(self, name: str) -> None:
        self.endpoint.mav.param_value_send(
            name.encode("ascii"),
            float(self.parameters.value(name)),
            _PARAM_TYPE_INT32,
            len(self.parameters),
            self.parameters.index(name),
        )

    async def _on_request_data_stream(self, message: Any) -> None:
        rate_hz = float(message.req_message_rate) if message.start_stop else 0.0
        self.schedule.set_stream(message.req_stream_id, rate_hz, self._clock())
        self.poller.set_rate(self._poll_rate_hz())

    async def _on_mission_request_list(self, message: Any) -> None:
        self.messages.mission_count(
            message.get_srcSystem(), message.get_srcComponent(), message.mission_type
        )

    async def _on_mission_upload(self, message: Any) -> None:
        """An upload (MISSION_COUNT): of nothing, accepted (the list stays empty); of items,
        refused at once, where a ground station left unanswered retries and times out."""
        result = _MISSION_ACCEPTED if message.count == 0 else _MISSION_UNSUPPORTED
        self._mission_ack(message, result)

    async def _on_mission_clear_all(self, message: Any) -> None:
        self._mission_ack(message, _MISSION_ACCEPTED)  # (there is nothing to clear)

    async def _on_mission_item_request(self, message: Any) -> None:
        self._mission_ack(message, _MISSION_INVALID_SEQUENCE)  # (there is no item)

    def _mission_ack(self, message: Any, result: int) -> None:
        self.messages.mission_ack(
            message.get_srcSystem(), message.get_srcComponent(), result, message.mission_type
        )

    async def _on_position_target(self, message: Any) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT's altitude as the depth to hold (ArduSub's way for a
        script to set one: ``alt`` −0.5 holds 50 cm), in ALT_HOLD and armed; its other fields
        (position, velocities, yaw) the protocol cannot carry out."""
        if message.type_mask & _POSITION_TARGET_Z_IGNORE:
            return
        why_not = None
        if message.coordinate_frame not in _DEPTH_TARGET_FRAMES:
            why_not = f"Depth target ignored: frame {message.coordinate_frame} is not global"
        elif self.state.mode is not FlightMode.ALT_HOLD or not self.armed:
            why_not = "Depth target ignored: ALT_HOLD and armed only"
        if why_not is not None:
            if why_not != self._depth_target_refusal:  # (a script may send one at 10 Hz)
                self._depth_target_refusal = why_not
                self._say(_SEVERITY_WARNING, why_not)
            return
        self._depth_target_refusal = None
        if math.isfinite(message.alt):
            await self.rov.send(self.pilot.hold(round(-message.alt * 100)))

    async def _on_timesync(self, message: Any) -> None:
        if message.tc1 == 0:  # a request (tc1 set: an answer, another system's)
            self.messages.timesync(message.ts1)

    async def _on_file_transfer(self, message: Any) -> None:
        payload = file_transfer.refusal(message.payload)
        if payload is not None:
            self.messages.file_transfer(
                message.get_srcSystem(), message.get_srcComponent(), payload
            )

    # -- internals -------------------------------------------------------------------------------

    def _on_reading(self, sensors: Sensors) -> None:
        now_s = self._clock()
        first_leak = self.state.update(sensors, now_s)
        if first_leak or (
            self.state.leak
            and self._leak_said_at_s is not None
            and now_s - self._leak_said_at_s >= self.leak_repeat_s
        ):
            self._leak_said_at_s = now_s
            self._say(_SEVERITY_CRITICAL, "Leak detected")
        if self.kept.pending:  # the controller answers again after a suspected reset
            self._in_background(self._restore_settings())

    def _on_client_event(self, event: ClientEvent) -> None:
        lost = isinstance(event, LinkState) and event.state == "lost"
        reset = isinstance(event, ResetSuspected)
        # (By a suspected reset the lock as last sent is forgotten already: the one known before
        # it says whether the vehicle may have been armed. Locked then, it is locked still, and
        # "Disarmed" would tell the pilot of a change that never was.)
        may_be_armed = self.messages.link_up and self._lock_known is not LockState.LOCKED
        # Losing the link stops the robot if the bridge unlocked it itself (sent_lock): a stop
        # heard since is no reason to send less (another line may have unlocked it again).
        armed_by_bridge = (
            self.messages.link_up and self.rov.commanded.sent_lock is LockState.UNLOCKED
        )
        if (lost and armed_by_bridge) or (reset and may_be_armed):
            # After a reset the controller is locked (P21): say so rather than show it armed.
            # (On a link being reopened, the #stop! waits to be its first frame.)
            reason = (
                "the controller link was lost" if lost else "controller silent (may have reset)"
            )
            self._in_background(self._disarm_quietly(reason))
        back = isinstance(event, LinkState) and event.state == "reconnected"
        if lost:
            self.messages.link_up = False
            self._say(_SEVERITY_CRITICAL, "Controller link lost: reopening it")
        elif back:
            self.messages.link_up = True
            self._say(_SEVERITY_INFO, "Controller link back")
        if isinstance(event, ResetSuspected) or back:
            # A reset, or a board that a reopened port may have reset (an Arduino's DTR line):
            # its settings are sent again once it answers.
            self.kept.reset_suspected()

    def _on_sent(self, sent: SentFrame) -> None:
        # What the pilot input measures changes and staleness against: the set-points as the
        # controller has them after each frame (whoever sent it), not what the bridge expects.
        self.pilot.sync(self.rov.commanded)
        if sent.command is not None and sent.command.name in _LOCK_COMMANDS:
            # (Only a lock change: the checksum mode the driver re-asserts on suspecting a
            # reset goes out after the reset made the lock unknown, before the bridge hears.)
            self._lock_known = self.rov.commanded.lock

    def _on_heard(self, announcement: Announcement) -> None:
        """The controller announced a lock change the bridge did not send (debug output on).
        A stop: the vehicle is DISARMED from the next HEARTBEAT on, and the next ARM sends
        ``#start!`` again. An unlock from another line leaves it disarmed: ARMED would make
        this ground station's sticks drive a robot its pilot never armed. Nothing is sent."""
        self.pilot.sync(self.rov.commanded)  # (a stop cleared the set-points)
        self._lock_known = self.rov.commanded.lock
        because = self.rov.commanded.heard_lock_because
        if announcement.kind is AnnouncementKind.LOCKED:
            self._say(_SEVERITY_WARNING, f"Disarmed: {because}")
        else:
            self._say(_SEVERITY_INFO, f"Motors {because}: ARM to drive from here")

    def _in_background(self, work: Coroutine[Any, Any, None]) -> None:
        task = asyncio.ensure_future(work)
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    async def _disarm_quietly(self, reason: str) -> None:
        with contextlib.suppress(ConnectionError):
            await self.disarm(reason)

    async def _restore_settings(self) -> None:
        """After a suspected reset, the parameters and the mode as last sent, sent again: the
        controller came back with its configured defaults, in depth mode (P21, P9)."""
        frames = await self.kept.restore_in_background(self.rov)
        if frames:
            logger.warning("the controller may have reset: sent again %s", frames)
            self._say(_SEVERITY_WARNING, "Controller reset? Parameters and mode sent again")

    async def _hold_current_depth(self, depth_cm: int) -> None:
        """In ALT_HOLD, armed: hold ``depth_cm``."""
        if self.state.mode is FlightMode.ALT_HOLD and self.armed:
            await self.rov.send(self.pilot.hold(depth_cm))

    def _poll_rate_hz(self) -> float:
        return min(max(self.schedule.fastest_rate_hz(), _MIN_POLL_HZ), MAX_RATE_HZ)

    def _message_name(self, message_id: int) -> str | None:
        message_class = self.endpoint.dialect.mavlink_map.get(message_id)
        return None if message_class is None else str(message_class.msgname)

    def _say(self, severity: int, text: str) -> None:
        self.messages.status_text(severity, text)


def _param_name(param_id: str | bytes) -> str:
    text = param_id.decode("ascii", "replace") if isinstance(param_id, bytes) else param_id
    return text.rstrip("\x00")
