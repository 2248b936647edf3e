"""The telemetry messages, filled from the vehicle state and sent through pymavlink."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import rovlink
from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint
from rovlink.bridges.mavlink.parameters import ParameterTable
from rovlink.bridges.mavlink.vehicle_state import VehicleState
from rovlink.piloting.commanded import LockState
from rovlink.piloting.tracked import TrackedClient

__all__ = [
    "READING_MESSAGES",
    "STATUSTEXT_CHARS",
    "TelemetryMessages",
    "statustext_chunks",
    "version_number",
]

_UNKNOWN_VOLTAGE_MV = 65535  # SYS_STATUS: no battery monitor
_UNKNOWN = -1
_UNKNOWN_HEADING = 0xFFFF  # GLOBAL_POSITION_INT.hdg
_INT16_MIN, _INT16_MAX = -0x8000, 0x7FFF  # GLOBAL_POSITION_INT.vz, cm/s
#: STATUSTEXT carries at most 50 characters; a longer text is sent in chunks (MAVLink 2).
STATUSTEXT_CHARS = 50
_LAST_STATUSTEXT_ID = 0xFFFF  # ``id`` is a uint16; 0 means "a text of one chunk"
#: The messages that carry the sensor readings: sent only while the readings are current
#: (:meth:`TelemetryMessages.readings_current`). A fresh ``time_boot_ms`` on the last reading
#: would show a silent controller's robot as it was, its climb rate and all, as if it were now.
READING_MESSAGES = frozenset({"ATTITUDE", "VFR_HUD", "GLOBAL_POSITION_INT", "SCALED_PRESSURE2"})


def statustext_chunks(text: str) -> list[bytes]:
    """``text`` in ASCII as STATUSTEXT chunks: 50 characters each, the last one shorter, since
    a NUL in a chunk is what marks it the last (an empty one follows a text of 50, 100… chars).

    >>> statustext_chunks("Armed")
    [b'Armed']
    >>> [len(chunk) for chunk in statustext_chunks("x" * 120)], statustext_chunks("y" * 50)[1:]
    ([50, 50, 20], [b''])
    """
    ascii_text = text.replace("–", "-").replace("…", "...").replace("−", "-")
    data = ascii_text.encode("ascii", "replace")
    if len(data) < STATUSTEXT_CHARS:
        return [data]
    return [
        data[start : start + STATUSTEXT_CHARS]
        for start in range(0, len(data) + 1, STATUSTEXT_CHARS)
    ]


def version_number(version: str) -> int:
    """A version as AUTOPILOT_VERSION's ``flight_sw_version``: major, minor, patch, type bytes.

    >>> hex(version_number("1.4.2"))
    '0x10402ff'
    """
    numbers = [int(part) for part in version.split(".")[:3] if part.isdigit()]
    major, minor, patch = ([*numbers, 0, 0, 0])[:3]
    return (major & 0xFF) << 24 | (minor & 0xFF) << 16 | (patch & 0xFF) << 8 | 0xFF


class TelemetryMessages:
    """Sends each telemetry message by name (``send("ATTITUDE")``) and the ones asked for once."""

    def __init__(
        self,
        endpoint: MavlinkEndpoint,
        state: VehicleState,
        rov: TrackedClient,
        parameters: ParameterTable,
        clock: Callable[[], float],
    ) -> None:
        self._endpoint = endpoint
        self._state = state
        self._rov = rov
        self._parameters = parameters
        self._clock = clock
        self._started_s = clock()
        self._statustext_id = 0
        #: False while the controller's link is lost and being reopened (the bridge says so).
        self.link_up = True
        self._senders: dict[str, Callable[[], None]] = {
            "HEARTBEAT": self.heartbeat,
            "SYS_STATUS": self.sys_status,
            "ATTITUDE": self.attitude,
            "VFR_HUD": self.vfr_hud,
            "GLOBAL_POSITION_INT": self.global_position_int,
            "SCALED_PRESSURE2": self.scaled_pressure2,
            "SYSTEM_TIME": self.system_time,
            "AUTOPILOT_VERSION": self.autopilot_version,
        }

    def names(self) -> list[str]:
        """Every message this can send."""
        return list(self._senders)

    def send(self, name: str) -> bool:
        """Send ``name`` now; ``False`` if it is not one of :meth:`names`."""
        sender = self._senders.get(name)
        if sender is None:
            return False
        sender()
        return True

    # -- the messages --------------------------------------------------------------------------

    @property
    def _mav(self) -> Any:
        return self._endpoint.mav

    @property
    def _dialect(self) -> Any:
        return self._endpoint.dialect

    def _boot_ms(self) -> int:
        return int((self._clock() - self._started_s) * 1000) & 0xFFFFFFFF

    @property
    def armed(self) -> bool:
        """Unlocked, as last sent, on a link that is open (the bridge stops a robot whose link
        was lost: the ``#stop!`` is the reopened link's first frame)."""
        return self.link_up and self._rov.commanded.lock is LockState.UNLOCKED

    def link_ok(self) -> bool:
        """Whether the controller answers (its queries are not failing, its link is open)."""
        return self.link_up and self._rov.health.status in {"ok", "waiting"}

    def readings_current(self) -> bool:
        """Whether the latest reading is the robot as it is now: there is one, none was missed
        since, and the controller answers (its last query did not fail, its link is open)."""
        return self._state.current and self.link_ok()

    def heartbeat(self, *, powering_off: bool = False) -> None:
        """HEARTBEAT: a submarine on ArduPilot, its custom mode, armed = unlocked.
        ``powering_off``: the bridge's last (MAV_STATE_POWEROFF)."""
        d = self._dialect
        base_mode = d.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | d.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        if self.armed:
            base_mode |= d.MAV_MODE_FLAG_SAFETY_ARMED
        if powering_off:
            status = d.MAV_STATE_POWEROFF
        elif self._state.leak or not self.link_ok():
            status = d.MAV_STATE_CRITICAL
        elif self.armed:
            status = d.MAV_STATE_ACTIVE
        else:
            status = d.MAV_STATE_STANDBY
        self._mav.heartbeat_send(
            d.MAV_TYPE_SUBMARINE,
            d.MAV_AUTOPILOT_ARDUPILOTMEGA,
            base_mode,
            int(self._state.mode),
            status,
        )

    def sys_status(self) -> None:
        """SYS_STATUS: the sensors behind ``qsa``, healthy while the controller answers; no
        fence (present, enabled: no; breached: no)."""
        d = self._dialect
        sensors = (
            d.MAV_SYS_STATUS_SENSOR_3D_GYRO
            | d.MAV_SYS_STATUS_SENSOR_3D_MAG
            | d.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
            | d.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        )
        enabled = sensors if self.armed else sensors & ~d.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
        healthy = sensors if self.link_ok() and self._state.sensors is not None else 0
        # No fence, and so none breached: its health bit set, as ArduPilot sets it (ground
        # stations read a fence's health whether or not one is present: MAVProxy said "fence
        # breach" on connecting).
        healthy |= d.MAV_SYS_STATUS_GEOFENCE
        health = self._rov.health
        attempts = health.replies + health.failures
        drop_rate = round(10000 * health.failures / attempts) if attempts else 0
        errors = min(self._rov.client.counters.bad_frames, 0xFFFF)
        self._mav.sys_status_send(
            sensors, enabled, healthy, 0, _UNKNOWN_VOLTAGE_MV, _UNKNOWN, _UNKNOWN,
            drop_rate, errors, 0, 0, 0, 0,
        )  # fmt: skip

    def attitude(self) -> None:
        """ATTITUDE: roll, pitch (``qro``, ``qpi``) and yaw (``qhe``); no rates."""
        roll, pitch, yaw = self._state.attitude_rad()
        self._mav.attitude_send(self._boot_ms(), roll, pitch, yaw, 0.0, 0.0, 0.0)

    def vfr_hud(self) -> None:
        """VFR_HUD: heading, altitude = −depth, climb, throttle = vertical thrust as last sent."""
        commanded = self._rov.commanded
        throttle = abs(commanded.vertical_thrust_percent)
        self._mav.vfr_hud_send(
            0.0,
            0.0,
            self._state.heading_deg(),
            throttle,
            self._state.altitude_m(),
            self._state.climb_cm_s / 100.0,
        )

    def global_position_int(self) -> None:
        """GLOBAL_POSITION_INT: no position fix (lat, lon 0); altitudes = −depth, mm; the heading
        UINT16_MAX (unknown, as MAVLink has it) until the first reading, not 0 (north)."""
        altitude_mm = round(self._state.altitude_m() * 1000)
        heading_cdeg = (
            _UNKNOWN_HEADING if self._state.sensors is None else self._state.heading_deg() * 100
        )
        self._mav.global_position_int_send(
            self._boot_ms(),
            0,
            0,
            altitude_mm,
            altitude_mm,
            0,
            0,
            # vz: + down, cm/s, as far as an int16 goes (a depth reading that jumped between
            # two fast polls is no reason for pymavlink to refuse the message, and end the bridge)
            max(_INT16_MIN, min(_INT16_MAX, round(-self._state.climb_cm_s))),
            heading_cdeg,
        )

    def scaled_pressure2(self) -> None:
        """SCALED_PRESSURE2 (ArduSub's depth sensor): from ``qr`` and the depth calibration."""
        pressure_hpa = self._state.absolute_pressure_hpa(
            self._parameters.value("RL_DEPTH_ZERO"), self._parameters.value("RL_DEPTH_K")
        )
        self._mav.scaled_pressure2_send(self._boot_ms(), pressure_hpa, 0.0, 0)

    def autopilot_version(self) -> None:
        """AUTOPILOT_VERSION: MAVLink 2, parameter values cast to PARAM_VALUE's float (as
        ArduPilot's: the flag MAVLink asks for, and the older one it replaced), COMMAND_INT;
        rovlink's version."""
        d = self._dialect
        capabilities = (
            d.MAV_PROTOCOL_CAPABILITY_MAVLINK2
            | d.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
            | d.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
            | d.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
        )
        self._mav.autopilot_version_send(
            capabilities, version_number(rovlink.__version__), 0, 0, 0,
            [0] * 8, [0] * 8, [0] * 8, 0, 0, 0,
        )  # fmt: skip

    def status_text(self, severity: int, text: str) -> None:
        """STATUSTEXT; a text longer than one carries goes in chunks with a common ``id``, as
        MAVLink 2 has it (a ground station joins them; none is cut)."""
        chunks = statustext_chunks(text)
        if len(chunks) == 1:
            self._mav.statustext_send(severity, chunks[0])
            return
        self._statustext_id = self._statustext_id % _LAST_STATUSTEXT_ID + 1  # 1…65535
        for sequence, chunk in enumerate(chunks):
            self._mav.statustext_send(severity, chunk, self._statustext_id, sequence)

    def mission_count(self, target_system: int, target_component: int, mission_type: int) -> None:
        """MISSION_COUNT 0: the robot runs no missions."""
        self._mav.mission_count_send(target_system, target_component, 0, mission_type)

    def mission_ack(
        self, target_system: int, target_component: int, result: int, mission_type: int
    ) -> None:
        """MISSION_ACK ``result`` (MAV_MISSION_RESULT) for the mission transfer of a ground
        station."""
        self._mav.mission_ack_send(target_system, target_component, result, mission_type)

    def system_time(self) -> None:
        """SYSTEM_TIME: this computer's clock (UTC, µs) and the time since the bridge started."""
        self._mav.system_time_send(int(time.time() * 1_000_000), self._boot_ms())

    def timesync(self, request_ts1: int) -> None:
        """TIMESYNC's answer to a request: ``tc1`` the time since the bridge started (ns, never 0:
        0 marks a request), ``ts1`` the request's (the asker matches its answer by it)."""
        now_ns = max(1, int((self._clock() - self._started_s) * 1_000_000_000))
        self._mav.timesync_send(now_ns, request_ts1)

    def message_interval(self, message_id: int, interval_us: int) -> None:
        """MESSAGE_INTERVAL: −1 not sent, 0 not available, else every ``interval_us`` µs."""
        self._mav.message_interval_send(message_id, interval_us)

    def file_transfer(self, target_system: int, target_component: int, payload: list[int]) -> None:
        """FILE_TRANSFER_PROTOCOL ``payload`` to whoever asked (network 0)."""
        self._mav.file_transfer_protocol_send(0, target_system, target_component, payload)
