"""What ground stations ask besides flying, answered at once as MAVLink has it: FTP, missions,
time, message intervals, results of commands the bridge knows but cannot carry out, the fence
bit of SYS_STATUS. A question left unanswered has a ground station retry and wait."""

from __future__ import annotations

import errno
import struct
import time

import pytest

from rovlink.bridges.mavlink.endpoint import MavlinkEndpoint
from rovlink.bridges.mavlink.file_transfer import ERROR_UNKNOWN_COMMAND, OPCODE_NAK
from tests.bridges.mavlink.rig import (
    VEHICLE,
    BridgeRig,
    GroundStation,
    free_udp_port,
    running_bridge,
    wait_for,
)

pytestmark = pytest.mark.integration

ACCEPTED, DENIED, UNSUPPORTED = 0, 2, 3
DO_SET_MODE, GET_MESSAGE_INTERVAL, SET_MESSAGE_INTERVAL, REQUEST_MESSAGE = 176, 510, 511, 512
STABILIZE, ALT_HOLD = 0, 2
HEARTBEAT_ID, SYSTEM_TIME_ID, ATTITUDE_ID, HOME_POSITION_ID = 0, 2, 30, 242
GEOFENCE = 0x100000  # MAV_SYS_STATUS_GEOFENCE
MISSION_ACCEPTED, MISSION_UNSUPPORTED, MISSION_INVALID_SEQUENCE = 0, 3, 13
FTP_OPEN_FILE_RO = 4
_FTP_HEADER = struct.Struct("<HBBBBBBI")


def test_ftp_is_refused_at_once_so_parameters_come_by_the_message_protocol(gcs: GroundStation):
    # MAVProxy asks for @PARAM/param.pck first, and retried for ten seconds when unanswered.
    name = b"@PARAM/param.pck"
    request = _FTP_HEADER.pack(41, 7, FTP_OPEN_FILE_RO, len(name), 0, 0, 0, 0) + name
    gcs.send("file_transfer_protocol", 0, VEHICLE, 1, list(request.ljust(251, b"\0")))
    reply = gcs.receive("FILE_TRANSFER_PROTOCOL", timeout_s=2.0)
    seq, session, opcode, size, req_opcode, *_ = _FTP_HEADER.unpack(bytes(reply.payload[:12]))
    assert (seq, session, opcode, size, req_opcode) == (42, 7, OPCODE_NAK, 1, FTP_OPEN_FILE_RO)
    assert reply.payload[12] == ERROR_UNKNOWN_COMMAND
    assert (reply.target_system, reply.target_component) == (255, 190)


def test_mission_uploads_and_clears_are_answered(gcs: GroundStation):
    gcs.send("mission_count", VEHICLE, 1, 3, 0)
    ack = gcs.receive("MISSION_ACK", timeout_s=2.0)
    assert (ack.type, ack.mission_type) == (MISSION_UNSUPPORTED, 0)
    assert (ack.target_system, ack.target_component) == (255, 190)
    gcs.send("mission_count", VEHICLE, 1, 0, 1)  # an empty fence: nothing to refuse
    assert gcs.receive("MISSION_ACK", timeout_s=2.0).type == MISSION_ACCEPTED
    gcs.send("mission_clear_all", VEHICLE, 1, 2)
    ack = gcs.receive("MISSION_ACK", timeout_s=2.0)
    assert (ack.type, ack.mission_type) == (MISSION_ACCEPTED, 2)
    gcs.send("mission_request_int", VEHICLE, 1, 0, 0)
    assert gcs.receive("MISSION_ACK", timeout_s=2.0).type == MISSION_INVALID_SEQUENCE


def test_timesync_is_answered_with_the_requests_timestamp(gcs: GroundStation):
    gcs.send("timesync", 0, 123456789)
    reply = gcs.receive("TIMESYNC", timeout_s=2.0)
    assert reply.ts1 == 123456789
    assert reply.tc1 > 0
    gcs.send("timesync", 5, 99)  # an answer, not a request: not answered
    gcs.send("timesync", 0, 100)
    assert gcs.receive("TIMESYNC", timeout_s=2.0).ts1 == 100


def test_system_time_is_sent_and_can_be_requested(gcs: GroundStation):
    gcs.receive_new("SYSTEM_TIME")  # unasked, as ArduPilot's (MAVProxy's `time` reads it)
    assert gcs.command(SET_MESSAGE_INTERVAL, SYSTEM_TIME_ID, -1) == ACCEPTED  # off ...
    before_us = time.time() * 1e6
    assert gcs.command(REQUEST_MESSAGE, SYSTEM_TIME_ID) == ACCEPTED  # ... but on request
    system_time = gcs.receive("SYSTEM_TIME", condition=lambda m: m.time_unix_usec >= before_us)
    assert system_time.time_unix_usec <= time.time() * 1e6


def test_message_intervals_can_be_read(gcs: GroundStation):
    assert gcs.command(SET_MESSAGE_INTERVAL, ATTITUDE_ID, 50_000) == ACCEPTED
    for message_id, interval_us in [(ATTITUDE_ID, 50_000), (HEARTBEAT_ID, 1_000_000),
                                    (HOME_POSITION_ID, 0)]:  # fmt: skip
        assert gcs.command(GET_MESSAGE_INTERVAL, message_id) == ACCEPTED
        reply = gcs.receive("MESSAGE_INTERVAL")
        assert (reply.message_id, reply.interval_us) == (message_id, interval_us)
    assert gcs.command(SET_MESSAGE_INTERVAL, ATTITUDE_ID, -1) == ACCEPTED
    assert gcs.command(GET_MESSAGE_INTERVAL, ATTITUDE_ID) == ACCEPTED
    assert gcs.receive("MESSAGE_INTERVAL", condition=lambda m: m.interval_us == -1)


def test_an_interval_or_message_id_message_interval_cannot_carry_is_denied(gcs: GroundStation):
    # MESSAGE_INTERVAL carries an int32 of µs (35 min) and a uint16 message id. Before, an
    # interval of an hour was accepted, and every GET_MESSAGE_INTERVAL for that message after
    # it (or for a message id beyond 65535) went unanswered: pymavlink could not pack the reply.
    an_hour_us = 3_600_000_000
    assert gcs.command(SET_MESSAGE_INTERVAL, ATTITUDE_ID, an_hour_us) == DENIED
    assert gcs.command(GET_MESSAGE_INTERVAL, ATTITUDE_ID) == ACCEPTED
    reply = gcs.receive("MESSAGE_INTERVAL", condition=lambda m: m.message_id == ATTITUDE_ID)
    assert reply.interval_us == 250_000  # the default 4 Hz, as before the refused change
    assert gcs.command(GET_MESSAGE_INTERVAL, 70_000) == DENIED


def test_a_known_command_asked_the_impossible_is_denied_not_unsupported(
    rig: BridgeRig, gcs: GroundStation
):
    mark = len(rig.frames())
    assert gcs.command(DO_SET_MODE, 1, STABILIZE) == DENIED
    assert gcs.command(DO_SET_MODE, 0, ALT_HOLD) == DENIED  # not a custom mode
    assert gcs.command(REQUEST_MESSAGE, HOME_POSITION_ID) == DENIED
    assert gcs.command(SET_MESSAGE_INTERVAL, HEARTBEAT_ID, 100_000) == DENIED  # stays 1 Hz
    assert gcs.command(SET_MESSAGE_INTERVAL, HOME_POSITION_ID, 100_000) == DENIED
    assert gcs.command(22) == UNSUPPORTED  # NAV_TAKEOFF: not a command the bridge knows
    assert all(f in {"#qsa!", "#qd!"} for f in rig.frames_since(mark))  # polls only


def test_no_fence_is_no_fence_breach(gcs: GroundStation):
    # MAVProxy's fence module says "fence breach" when the health bit is clear.
    status = gcs.receive_new("SYS_STATUS")
    assert status.onboard_control_sensors_health & GEOFENCE
    assert not status.onboard_control_sensors_present & GEOFENCE
    assert not status.onboard_control_sensors_enabled & GEOFENCE


def _depth_target(gcs: GroundStation, alt_m: float, *, frame: int = 5, type_mask: int = 0) -> None:
    # ArduSub's pymavlink example for a depth in ALT_HOLD: everything but z ignored.
    mask = type_mask or 0b0000_1111_1111_1011  # all but POSITION_TARGET_TYPEMASK_Z_IGNORE
    gcs.send("set_position_target_global_int", 0, VEHICLE, 1, frame, mask, 0, 0, alt_m,
             0, 0, 0, 0, 0, 0, 0, 0)  # fmt: skip


def test_a_depth_target_is_held_in_alt_hold_as_ardusub_takes_it(rig: BridgeRig, gcs: GroundStation):
    mark = len(rig.frames())
    _depth_target(gcs, -1.5)  # disarmed, MANUAL: refused, and said
    gcs.receive("STATUSTEXT", condition=lambda m: "ALT_HOLD and armed only" in m.text)
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    assert gcs.set_mode(ALT_HOLD) == ACCEPTED
    rig.wait_frame("#mvdirect.0!", since=mark)
    _depth_target(gcs, -1.5)
    rig.wait_frame("#mvd.150!", since=mark)
    _depth_target(gcs, -0.4, frame=6)  # relative altitude: the same, without a position
    rig.wait_frame("#mvd.40!", since=mark)
    _depth_target(gcs, -2.0, type_mask=0xFFF)  # z ignored too: nothing to do
    _depth_target(gcs, -2.0, frame=1)  # MAV_FRAME_LOCAL_NED: not taken, and said
    gcs.receive("STATUSTEXT", condition=lambda m: "frame 1" in m.text)
    assert not [f for f in rig.frames_since(mark) if f.startswith("#mvd.200")]


def test_a_udp_port_another_bridge_listens_on_is_refused() -> None:
    # pymavlink binds with SO_REUSEADDR: a second bridge on the same port started, and each
    # ground station datagram (a disarm among them) went to one of the two.
    port = free_udp_port()
    first = MavlinkEndpoint(f"udpin:127.0.0.1:{port}")
    try:
        with pytest.raises(OSError, match="in use") as refused:
            MavlinkEndpoint(f"udpin:127.0.0.1:{port}")
        assert refused.value.errno == errno.EADDRINUSE
    finally:
        first.close()
    MavlinkEndpoint(f"udpin:127.0.0.1:{port}").close()  # free again: taken


def test_a_leak_is_said_again_while_the_latch_is_set_for_a_late_ground_station() -> None:
    # Said once only, a ground station connecting later saw a CRITICAL vehicle and no reason.
    with running_bridge(leak_at_s=0.2) as rig:
        rig.bridge.leak_repeat_s = 0.3  # (ArduSub's 20 s, shortened)
        wait_for(lambda: rig.bridge.state.leak)
        late = GroundStation(rig.gcs_address)
        try:
            late.receive("STATUSTEXT", condition=lambda m: m.text == "Leak detected")
            said_s = time.monotonic()
            text = late.receive("STATUSTEXT", condition=lambda m: m.text == "Leak detected")
            assert text.severity == 2  # MAV_SEVERITY_CRITICAL
            assert time.monotonic() - said_s >= 0.2
        finally:
            late.close()


def test_a_joystick_aimed_at_every_vehicle_drives_none_and_is_said_once(
    rig: BridgeRig, gcs: GroundStation
):
    # A script that never read the vehicle's id sends MANUAL_CONTROL to system 0: ArduSub
    # ignores it, and so does the bridge; before, without a word.
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    for _ in range(3):
        gcs.send("manual_control", 0, 500, 0, 500, 0, 0)
    text = gcs.receive("STATUSTEXT", condition=lambda m: "system 0" in m.text)
    assert text.text == "Joystick to system 0 ignored: aim it at 1"
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)  # aimed: drives (centred)
    gcs.send("manual_control", VEHICLE, 500, 0, 500, 0, 0)
    rig.wait_frame("#th.0.50!", since=mark)
    assert gcs.command(REQUEST_MESSAGE, SYSTEM_TIME_ID) == ACCEPTED  # (what came before: read)
    assert not [m for m in gcs.kept("STATUSTEXT") if "system 0" in m.text]  # said once
    assert [f for f in rig.frames_since(mark) if f.startswith("#th")] == ["#th.0.50!"]
