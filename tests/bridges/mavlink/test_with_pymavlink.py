"""The MAVLink bridge against pymavlink as a ground station, over real UDP, on the simulator:
what reaches the serial line is read from a recording link."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from rovlink.bridges.mavlink.failsafe import GCS_TIMEOUT_S
from rovlink.bridges.mavlink.parameters import ParameterTable
from rovlink.protocol import VerticalMode
from tests.bridges.mavlink.rig import (
    VEHICLE,
    BridgeRig,
    GroundStation,
    free_tcp_port,
    free_udp_port,
    running_bridge,
    wait_for,
)

pytestmark = pytest.mark.integration

SUBMARINE = 12
ARDUPILOTMEGA = 3
MANUAL, ALT_HOLD, STABILIZE = 19, 2, 0
ARMED_FLAG = 128
POWEROFF = 7  # MAV_STATE_POWEROFF
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4
STANDBY, CRITICAL = 3, 5  # MAV_STATE
ARM_DISARM, DO_SET_MODE, DO_GRIPPER = 400, 176, 211
SET_MODE_ID = 11  # the SET_MODE message's id: ArduPilot's COMMAND_ACK.command for it
SET_MESSAGE_INTERVAL, REQUEST_MESSAGE = 511, 512
NAV_TAKEOFF = 22
SYSTEM_TIME_ID, ATTITUDE_ID, AUTOPILOT_VERSION_ID = 2, 30, 148


def _armed(gcs: GroundStation) -> bool:
    heartbeat = gcs.receive_new("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
    return bool(heartbeat.base_mode & ARMED_FLAG)


def test_a_ground_station_sees_a_disarmed_submarine_in_manual(rig: BridgeRig, gcs: GroundStation):
    heartbeat = gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
    assert heartbeat.autopilot == ARDUPILOTMEGA
    assert heartbeat.custom_mode == MANUAL
    assert not heartbeat.base_mode & ARMED_FLAG
    assert heartbeat.get_srcSystem() == VEHICLE
    # The bridge started the robot locked, in direct (MANUAL) mode.
    assert rig.frames()[1:3] == ["#stop!", "#mvdirect.1!"]  # after the checksum mode


def test_autopilot_version_on_request_and_an_empty_mission(gcs: GroundStation):
    assert gcs.command(REQUEST_MESSAGE, AUTOPILOT_VERSION_ID) == ACCEPTED
    version = gcs.receive("AUTOPILOT_VERSION")
    assert version.capabilities & 8192  # MAV_PROTOCOL_CAPABILITY_MAVLINK2
    # How parameter values sit in PARAM_VALUE's float: cast, as ArduPilot's (MAVLink asks for
    # this flag or BYTEWISE; without either a ground station may read 40 as 1109393408).
    assert version.capabilities & 131072  # MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST
    assert not version.capabilities & 16  # MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    gcs.send("mission_request_list", VEHICLE, 1, 0)
    assert gcs.receive("MISSION_COUNT").count == 0


def test_telemetry_carries_the_sensors(rig: BridgeRig, gcs: GroundStation):
    wait_for(lambda: rig.bridge.state.sensors is not None)
    attitude = gcs.receive("ATTITUDE")
    hud = gcs.receive("VFR_HUD")
    position = gcs.receive("GLOBAL_POSITION_INT")
    pressure = gcs.receive("SCALED_PRESSURE2")
    sensors = rig.bridge.state.sensors
    assert sensors is not None
    assert hud.heading in {(sensors.heading_deg + d) % 360 for d in (-2, -1, 0, 1, 2)}
    assert abs(attitude.yaw) <= 3.1416
    assert position.relative_alt <= 0  # altitude is −depth
    assert pressure.press_abs >= 1013.0
    gcs.receive("SYS_STATUS")


def test_the_parameter_list_and_a_gain_set_on_the_wire(rig: BridgeRig, gcs: GroundStation):
    gcs.send("param_request_list", VEHICLE, 1)
    table = ParameterTable()
    received: dict[str, float] = {}
    while len(received) < len(table):
        value = gcs.receive("PARAM_VALUE")
        assert value.param_count == len(table)
        received[value.param_id] = value.param_value
    assert received["RL_DEPTH_P"] == 40
    assert received["BTN6_FUNCTION"] == 3  # ArduSub's default: arm

    mark = len(rig.frames())
    gcs.send("param_set", VEHICLE, 1, b"RL_DEPTH_P", 33.0, 6)
    echoed = gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "RL_DEPTH_P")
    assert echoed.param_value == 33
    rig.wait_frame("#mvpdp.33!", since=mark)


def test_a_refused_parameter_keeps_its_value_and_sends_nothing(rig: BridgeRig, gcs: GroundStation):
    mark = len(rig.frames())
    gcs.send("param_set", VEHICLE, 1, b"RL_DEPTH_P", 120.0, 6)
    echoed = gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "RL_DEPTH_P")
    assert echoed.param_value == 40
    text = gcs.receive("STATUSTEXT", condition=lambda m: "RL_DEPTH_P" in m.text)
    assert "120" in text.text  # what was refused, named
    assert not [f for f in rig.frames_since(mark) if f.startswith("#mvp")]


def test_arm_then_the_joystick_drives_and_yaw_is_ignored(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    mark = len(rig.frames())
    assert gcs.arm() == ACCEPTED
    rig.wait_frame("#start!", since=mark)
    wait_for(lambda: _armed(gcs))

    gcs.send("manual_control", VEHICLE, 0, 1000, 1000, 0, 0)  # right, full up
    rig.wait_frame("#th.90.100!", since=mark)
    rig.wait_frame("#mvs.+100!", since=mark)
    moved = len(rig.frames())
    gcs.send("manual_control", VEHICLE, 0, 1000, 1000, 800, 0)  # the same, plus yaw
    gcs.send("manual_control", VEHICLE, 0, 1000, 500, 0, 0)  # vertical neutral: a marker
    rig.wait_frame("#mvs.+0!", since=moved)
    motion = [f for f in rig.frames_since(moved) if f.startswith(("#th", "#mvs"))]
    assert motion == ["#mvs.+0!"]  # yaw sent nothing

    assert gcs.command(ARM_DISARM, 0) == ACCEPTED
    rig.wait_frame("#stop!", since=moved)


def test_heartbeat_loss_while_armed_stops_the_robot(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    gcs.send("manual_control", VEHICLE, 1000, 0, 500, 0, 0)
    rig.wait_frame("#th.0.100!")
    mark = len(rig.frames())
    gcs.stop_heartbeats()
    rig.wait_frame("#stop!", since=mark)
    # Not before the 3 s: measured from the last beat sent (the bridge had it later), not from
    # the heartbeat thread's end, which a loaded machine delays into the 3 s.
    assert gcs.last_heartbeat_s is not None
    assert time.monotonic() - gcs.last_heartbeat_s >= GCS_TIMEOUT_S
    gcs.receive("STATUSTEXT", condition=lambda m: "heartbeat" in m.text.lower())
    assert not _armed(gcs)


def test_no_stop_while_the_ground_station_beats(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    deadline = time.monotonic() + 4.5  # longer than the failsafe's 3 s
    while time.monotonic() < deadline:
        gcs.send("manual_control", VEHICLE, 1000, 0, 500, 0, 0)
        time.sleep(0.05)
    assert "#stop!" not in rig.frames_since(mark)
    assert _armed(gcs)


@pytest.mark.parametrize("input_kind", ["manual_control", "rc_channels_override"])
def test_the_pilots_joystick_is_contact_as_a_heartbeat_is(
    rig: BridgeRig, gcs: GroundStation, input_kind: str
):
    # ArduSub takes the pilot's MANUAL_CONTROL and RC overrides as heartbeats: its pymavlink
    # examples fly without sending any. The bridge stopped such a script 3 s after arming.
    rig.bridge.watchdog.timeout_s = 0.8  # (3 s in use: the same rule, sooner)
    assert gcs.arm() == ACCEPTED  # (contact: no heartbeat from here on)
    mark = len(rig.frames())
    started_s = time.monotonic()
    while time.monotonic() - started_s < 1.0:  # longer than the failsafe's timeout
        if input_kind == "manual_control":
            gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)
        else:
            gcs.send("rc_channels_override", VEHICLE, 1, *[1500] * 8)
        time.sleep(0.05)
    _served_since(gcs)
    assert "#stop!" not in rig.frames_since(mark)
    rig.wait_frame("#stop!", since=mark)  # the input stops: the ground station is lost


def test_stale_joystick_input_zeroes_the_thrust_but_stays_armed(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    last_input_s = time.monotonic()  # (before the send: see the RC override's test)
    gcs.send("manual_control", VEHICLE, 0, -1000, 250, 0, 0)  # left, down at half
    rig.wait_frame("#th.270.100!", since=mark)
    rig.wait_frame("#mvs.-50!", since=mark)
    rig.wait_frame("#th.270.0!", since=mark)
    assert time.monotonic() - last_input_s >= 0.9
    rig.wait_frame("#mvs.+0!", since=mark)
    assert "#stop!" not in rig.frames_since(mark)
    gcs.receive("STATUSTEXT", condition=lambda m: "stale" in m.text)


def test_alt_hold_holds_the_current_depth_and_the_stick_moves_it(
    rig: BridgeRig, gcs: GroundStation
):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    assert gcs.set_mode(ALT_HOLD) == ACCEPTED
    rig.wait_frame("#mvdirect.0!", since=mark)
    held = next(f for f in _wait_prefix(rig, "#mvd.", mark))
    depth_cm = int(held[len("#mvd.") : -1])
    heartbeat = gcs.receive_new(
        "HEARTBEAT", condition=lambda m: m.type == SUBMARINE and m.custom_mode == ALT_HOLD
    )
    assert heartbeat.base_mode & ARMED_FLAG
    # Throttle down (z below 500) for a while moves the target deeper.
    for _ in range(20):
        gcs.send("manual_control", VEHICLE, 0, 0, 0, 0, 0)
        time.sleep(0.05)
    targets = [int(f[len("#mvd.") : -1]) for f in rig.frames_since(mark) if f.startswith("#mvd.")]
    assert max(targets) > depth_cm
    assert not [f for f in rig.frames_since(mark) if f.startswith("#mvs")]  # no thrust in depth
    # ALT_HOLD asked again (a retry, the depth-hold button) keeps the target the stick set; it
    # once went back to the depth of the moment, which the robot had not reached yet.
    moved = len(rig.frames())
    assert gcs.set_mode(ALT_HOLD) == ACCEPTED
    assert not [f for f in rig.frames_since(moved) if f.startswith("#mvd.")]
    assert gcs.set_mode(MANUAL) == ACCEPTED
    rig.wait_frame("#mvdirect.1!", since=mark)


def test_depth_hold_engaged_while_diving_holds_the_depth_of_that_moment(
    rig: BridgeRig, gcs: GroundStation
):
    # The held depth was the last sensor poll's (4 Hz: up to 0.25 s old, 2 Hz when telemetry is
    # slow), sent over the controller's own hold of the moment (P9): a robot diving at 0.9 m/s
    # was sent up to tens of cm back up. Here the polls are made rare, so the last is old.
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    rig.bridge.poller.rate_hz = 0.1  # (from the next poll on: the one after is 10 s later)
    polled = rig.bridge.state.sensors
    wait_for(lambda: rig.bridge.state.sensors is not polled)
    vehicle = rig.port.robot.vehicle
    started_s = time.monotonic()
    while time.monotonic() - started_s < 1.0:  # full down: the robot dives
        gcs.send("manual_control", VEHICLE, 0, 0, 0, 0, 0)
        time.sleep(0.05)
    mark = len(rig.frames())
    before_cm = vehicle.depth_m * 100
    assert gcs.set_mode(ALT_HOLD) == ACCEPTED
    held = int(_wait_prefix(rig, "#mvd.", mark)[0][len("#mvd.") : -1])
    after_cm = vehicle.depth_m * 100
    assert after_cm - (rig.bridge.state.depth_cm or 0) > 25  # (the last poll's is that old)
    assert before_cm - 10 <= held <= after_cm + 10  # (10: the sensor's noise and resolution)


def _wait_prefix(rig: BridgeRig, prefix: str, since: int) -> list[str]:
    wait_for(lambda: any(f.startswith(prefix) for f in rig.frames_since(since)))
    return [f for f in rig.frames_since(since) if f.startswith(prefix)]


def test_unsupported_modes_are_denied_and_unknown_commands_unsupported(
    rig: BridgeRig, gcs: GroundStation
):
    mark = len(rig.frames())
    assert gcs.set_mode(STABILIZE) == DENIED
    assert gcs.command(NAV_TAKEOFF) == UNSUPPORTED
    assert all(f in {"#qsa!", "#qd!"} for f in rig.frames_since(mark))  # polls only


@pytest.mark.parametrize(("mode", "result"), [(ALT_HOLD, ACCEPTED), (STABILIZE, DENIED)])
def test_set_mode_is_acknowledged_as_ardupilot_does(
    rig: BridgeRig, gcs: GroundStation, mode: int, result: int
):
    # ArduSub's pymavlink example changes the mode with SET_MODE and waits for the COMMAND_ACK
    # whose command is MAVLINK_MSG_ID_SET_MODE (11), as ArduPilot sends it; an ack for 176 it
    # never takes, and waits for ever.
    mark = len(rig.frames())
    gcs.send("set_mode", VEHICLE, 1, mode)  # MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    ack = gcs.receive("COMMAND_ACK", condition=lambda m: m.command in (SET_MODE_ID, DO_SET_MODE))
    assert (ack.command, ack.result) == (SET_MODE_ID, result)
    assert (ack.target_system, ack.target_component) == (255, 190)
    if result == ACCEPTED:
        rig.wait_frame("#mvdirect.0!", since=mark)


def test_the_gripper_needs_arming(rig: BridgeRig, gcs: GroundStation):
    assert gcs.command(DO_GRIPPER, 1, 1) == DENIED
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    assert gcs.command(DO_GRIPPER, 1, 1) == ACCEPTED
    rig.wait_frame("#h-!", since=mark)
    assert gcs.command(DO_GRIPPER, 1, 0) == ACCEPTED
    rig.wait_frame("#h+!", since=mark)


def test_a_button_arms_with_ardusubs_default_mapping(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    mark = len(rig.frames())
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 1 << 6)  # BTN6: arm
    rig.wait_frame("#start!", since=mark)
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 1 << 4)  # BTN4: disarm
    rig.wait_frame("#stop!", since=mark)


def test_arming_needs_a_disarm_button_as_in_ardusub(rig: BridgeRig, gcs: GroundStation):
    # Underwater the pilot's hands are on the joystick: ArduSub refuses to arm without a button
    # that disarms ("PreArm: Must assign a disarm or arm_toggle button"); the bridge armed.
    gcs.start_heartbeats()
    gcs.send("param_set", VEHICLE, 1, b"BTN4_FUNCTION", 5, 6)  # disarm → MANUAL: none left
    assert (
        gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "BTN4_FUNCTION").param_value
        == 5
    )
    mark = len(rig.frames())
    assert gcs.arm() == FAILED
    assert "disarm" in gcs.receive("STATUSTEXT", condition=lambda m: "PreArm" in m.text).text
    gcs.send("param_set", VEHICLE, 1, b"BTN20_FUNCTION", 2, 6)  # arm toggle, in buttons2
    gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "BTN20_FUNCTION")
    assert "#start!" not in rig.frames_since(mark)
    assert gcs.arm() == ACCEPTED
    rig.wait_frame("#start!", since=mark)


@pytest.mark.realtime
def test_message_interval_raises_a_rate(rig: BridgeRig, gcs: GroundStation):
    assert gcs.command(SET_MESSAGE_INTERVAL, ATTITUDE_ID, 50_000) == ACCEPTED  # 20 Hz
    gcs.receive("ATTITUDE")
    started_s = time.monotonic()
    count = 0
    while count < 15:
        gcs.receive("ATTITUDE")
        count += 1
    # 15 at the default 4 Hz would take 3.75 s.
    assert time.monotonic() - started_s < 2.5
    assert rig.bridge.poller.rate_hz >= 20
    assert gcs.command(SET_MESSAGE_INTERVAL, 0, 100_000) == DENIED  # HEARTBEAT: 1 Hz


def test_disarm_is_accepted_even_when_not_armed(rig: BridgeRig, gcs: GroundStation):
    mark = len(rig.frames())
    assert gcs.command(ARM_DISARM, 0) == ACCEPTED
    rig.wait_frame("#stop!", since=mark)


def test_a_leak_is_a_critical_statustext():
    with running_bridge(leak_at_s=0.5) as rig:
        gcs = GroundStation(rig.gcs_address)
        try:
            text = gcs.receive("STATUSTEXT", condition=lambda m: "Leak" in m.text)
            assert text.severity == 2  # MAV_SEVERITY_CRITICAL
            heartbeat = gcs.receive_new("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            assert heartbeat.system_status == 5  # MAV_STATE_CRITICAL
        finally:
            gcs.close()


def test_ending_the_bridge_locks_the_robot():
    with running_bridge() as rig:
        gcs = GroundStation(rig.gcs_address)
        try:
            gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            gcs.start_heartbeats()
            assert gcs.arm() == ACCEPTED
            mark = len(rig.frames())
        finally:
            gcs.close()
    assert "#stop!" in rig.frames_since(mark)


def test_a_ground_station_is_told_the_bridge_stopped_and_the_vehicle_disarmed():
    # Before, the bridge went silent: a ground station showed the vehicle armed until it
    # noticed the silence, seconds later.
    with running_bridge() as rig:
        gcs = GroundStation(rig.gcs_address)
        gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
        gcs.start_heartbeats()
        assert gcs.arm() == ACCEPTED
        assert _armed(gcs)
    try:
        said = gcs.receive("STATUSTEXT", condition=lambda m: m.text.startswith("Bridge stopped"))
        assert said.text == "Bridge stopped: motors locked (#stop! sent)"
        last = gcs.receive_new("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
        assert not last.base_mode & ARMED_FLAG
        assert last.system_status == POWEROFF
    finally:
        gcs.close()


def test_telemetry_to_a_broadcast_address_reaches_the_ground_station():
    # A topside network whose ground station's address is not known beforehand: the bridge sends
    # to the subnet's broadcast address (here loopback's). Every send failed (EACCES: the socket
    # was not allowed to broadcast; pymavlink drops the error), though the bridge said "ready".
    port = free_udp_port()
    with running_bridge(endpoint=f"udpout:127.255.255.255:{port}") as rig:
        gcs = GroundStation(f"udpin:0.0.0.0:{port}")
        try:
            gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            gcs.heartbeat()  # and the ground station's answers come back
            mark = len(rig.frames())
            assert gcs.arm() == ACCEPTED
            rig.wait_frame("#start!", since=mark)
        finally:
            gcs.close()


def test_a_ground_station_over_tcp():
    port = free_tcp_port()
    with running_bridge(endpoint=f"tcpin:127.0.0.1:{port}") as rig:
        gcs = GroundStation(f"tcp:127.0.0.1:{port}")
        try:
            gcs.heartbeat()
            heartbeat = gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            assert heartbeat.custom_mode == MANUAL
            gcs.start_heartbeats()
            mark = len(rig.frames())
            assert gcs.arm() == ACCEPTED
            rig.wait_frame("#start!", since=mark)
        finally:
            gcs.close()


@pytest.mark.slow  # (six ground stations in turn: the race needed that many to show)
def test_tcp_ground_stations_come_and_go_and_the_next_one_is_served():
    # pymavlink swaps a TCP socket when a write finds the peer gone; a read at the same time
    # once killed the reader thread, and the bridge heard no ground station again.
    port = free_tcp_port()
    with running_bridge(endpoint=f"tcpin:127.0.0.1:{port}"):
        for _ in range(6):
            gcs = GroundStation(f"tcp:127.0.0.1:{port}")
            try:
                gcs.heartbeat()
                gcs.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
                assert gcs.command(REQUEST_MESSAGE, AUTOPILOT_VERSION_ID) == ACCEPTED
            finally:
                gcs.close()
            time.sleep(1.5)  # telemetry meets the closed socket meanwhile


def test_the_bridge_dials_a_restarted_tcp_ground_station_again():
    port = free_tcp_port()
    server = GroundStation(f"tcpin:127.0.0.1:{port}")
    try:
        with running_bridge(endpoint=f"tcp:127.0.0.1:{port}"):
            for _ in range(2):
                server.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
                server.send("command_long", VEHICLE, 1, REQUEST_MESSAGE, 0, AUTOPILOT_VERSION_ID,
                            0, 0, 0, 0, 0, 0)  # fmt: skip
                assert server.receive("COMMAND_ACK").result == ACCEPTED
                server.close()  # the ground station restarts
                server = GroundStation(f"tcpin:127.0.0.1:{port}")
    finally:
        server.close()


def test_a_tcp_ground_station_that_starts_after_the_bridge_is_dialled(
    capsys: pytest.CaptureFixture[str],
):
    # The vehicle's computer boots before the ground station's: the bridge serves on and dials
    # it (pymavlink's client gave up after its retries, printing, and the bridge ended).
    port = free_tcp_port()
    with running_bridge(endpoint=f"tcp:127.0.0.1:{port}") as rig:
        server = GroundStation(f"tcpin:127.0.0.1:{port}")
        try:
            server.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            server.heartbeat()
            server.start_heartbeats()
            mark = len(rig.frames())
            assert server.arm() == ACCEPTED
            rig.wait_frame("#start!", since=mark)
        finally:
            server.close()
    assert capsys.readouterr().out == ""  # (pymavlink's "Connection refused sleeping")


def test_nonsense_values_are_denied_and_the_bridge_serves_on(rig: BridgeRig, gcs: GroundStation):
    nan = float("nan")
    assert gcs.command(REQUEST_MESSAGE, nan) == DENIED
    assert gcs.command(DO_SET_MODE, nan, nan) == DENIED
    gcs.send("param_set", VEHICLE, 1, b"RL_DEPTH_K", nan, 6)
    echoed = gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "RL_DEPTH_K")
    assert echoed.param_value == 200
    gcs.send("param_set", VEHICLE, 1, b"NO_SUCH_PARAM", 1.0, 6)
    gcs.receive("STATUSTEXT", condition=lambda m: "NO_SUCH_PARAM" in m.text)
    assert gcs.command(REQUEST_MESSAGE, AUTOPILOT_VERSION_ID) == ACCEPTED  # still serving


def test_parameters_from_a_file_are_sent_on_start_and_only_they():
    with running_bridge(send_on_start=("RL_DEPTH_P", "RL_MAX_PWM", "BTN3_FUNCTION")) as rig:
        rig.wait_frame("#mgmp.255!")
        start = rig.frames()[: rig.frames().index("#mgmp.255!") + 1]
        assert start[1:] == ["#stop!", "#mvdirect.1!", "#mvpdp.40!", "#mgmp.255!"]
        assert not [f for f in rig.frames() if f.startswith(("#sdz", "#sdk", "#mvpdi"))]


def _change_mode_or_re_arm(gcs: GroundStation, change: str) -> None:
    """What reset the bridge's idea of the thrust, though the controller keeps it (P7, P9, P11)."""
    if change == "mode command":
        assert gcs.set_mode(MANUAL) == ACCEPTED  # MANUAL again: #mvdirect.1! changes nothing
    elif change == "SET_MODE":
        gcs.send("set_mode", VEHICLE, 1, MANUAL)
        gcs.receive("COMMAND_ACK", condition=lambda m: m.command == SET_MODE_ID)
    elif change == "mode button":
        gcs.send("manual_control", VEHICLE, 1000, 0, 0, 0, 1 << 1)  # BTN1: MANUAL
    elif change == "re-arm":
        assert gcs.arm() == ACCEPTED  # armed already: nothing is sent
    else:  # "depth hold": vertical thrust 0 (the controller's), horizontal kept
        assert gcs.set_mode(ALT_HOLD) == ACCEPTED


@pytest.mark.parametrize("then", ["input stops", "stick centred"])
@pytest.mark.parametrize(
    "change", ["mode command", "SET_MODE", "mode button", "re-arm", "depth hold"]
)
def test_thrust_kept_across_a_mode_change_or_re_arm_is_still_zeroed(
    rig: BridgeRig, gcs: GroundStation, change: str, then: str
):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    gcs.send("manual_control", VEHICLE, 1000, 0, 0, 0, 0)  # full ahead, full down
    rig.wait_frame("#th.0.100!", since=mark)
    rig.wait_frame("#mvs.-100!", since=mark)
    _change_mode_or_re_arm(gcs, change)
    if change != "re-arm":
        rig.wait_frame("#mvdirect.0!" if change == "depth hold" else "#mvdirect.1!", since=mark)
    changed = len(rig.frames())
    expected = ["#th.0.0!"] if change == "depth hold" else ["#th.0.0!", "#mvs.+0!"]
    if then == "stick centred":
        gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)
    for frame in expected:
        rig.wait_frame(frame, since=changed)  # before: nothing, and the robot drove on
    assert "#stop!" not in rig.frames_since(mark)


def _served_since(gcs: GroundStation) -> None:
    """Wait until what was sent before has been handled: messages are served in order."""
    gcs.send("command_long", VEHICLE, 0, REQUEST_MESSAGE, 0, AUTOPILOT_VERSION_ID, *[0.0] * 6)
    gcs.receive("COMMAND_ACK", condition=lambda m: m.command == REQUEST_MESSAGE)  # component 0


def test_the_joystick_of_another_system_does_not_drive_this_one(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    gcs.send("manual_control", 2, 0, 1000, 1000, 0, 0)  # for system 2: right, full up
    # A joystick broadcast (target 0) drives no vehicle, as in ArduSub, which takes
    # MANUAL_CONTROL aimed at it only: it once drove every vehicle on the network at once.
    gcs.send("manual_control", 0, 0, 1000, 1000, 0, 0)
    _served_since(gcs)
    assert not [f for f in rig.frames_since(mark) if f.startswith(("#th", "#mvs"))]
    gcs.send("manual_control", VEHICLE, 0, 1000, 1000, 0, 0)
    rig.wait_frame("#th.90.100!", since=mark)


def test_only_the_pilots_ground_station_flies_and_keeps_the_vehicle_armed():
    # Two ground stations: the pilot's (system 255, SYSID_MYGCS) and a second one whose idle
    # joystick sends a centred stick. The second's input once took turns with the pilot's at
    # the thrust (full ahead, zero, full ahead, … at the joysticks' rate), and its heartbeat
    # kept the vehicle armed after the pilot's ground station had gone.
    port = free_udp_port()
    with running_bridge(endpoint=f"udpin:127.0.0.1:{port}") as rig:
        pilot = GroundStation(f"udpout:127.0.0.1:{port}")
        watcher = GroundStation(f"udpout:127.0.0.1:{port}", system=254)
        try:
            pilot.heartbeat()
            pilot.receive("HEARTBEAT", condition=lambda m: m.type == SUBMARINE)
            assert pilot.arm() == ACCEPTED
            pilot.start_heartbeats()
            mark = len(rig.frames())
            pilot.send("manual_control", VEHICLE, 1000, 0, 500, 0, 0)
            rig.wait_frame("#th.0.100!", since=mark)
            for _ in range(20):
                watcher.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)
                watcher.heartbeat()
                pilot.send("manual_control", VEHICLE, 1000, 0, 500, 0, 0)
                time.sleep(0.05)
            assert [f for f in rig.frames_since(mark) if f.startswith("#th")] == ["#th.0.100!"]
            assert rig.bridge.armed

            pilot.stop_heartbeats()  # the pilot's ground station goes; the other one beats on
            gone = len(rig.frames())
            deadline = time.monotonic() + 6.0
            while "#stop!" not in rig.frames_since(gone) and time.monotonic() < deadline:
                watcher.heartbeat()
                time.sleep(0.2)
            assert "#stop!" in rig.frames_since(gone)
        finally:
            pilot.close()
            watcher.close()


def test_messages_for_another_component_of_this_system_are_ignored(
    rig: BridgeRig, gcs: GroundStation
):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    camera = 100
    gcs.send("command_long", VEHICLE, camera, ARM_DISARM, 0, *[0.0] * 7)  # disarm the camera
    gcs.send("param_set", VEHICLE, camera, b"RL_DEPTH_P", 33.0, 6)
    _served_since(gcs)
    assert not [f for f in rig.frames_since(mark) if f.startswith(("#stop", "#mvpdp"))]
    assert rig.bridge.parameters.value("RL_DEPTH_P") == 40
    assert not [ack for ack in gcs.kept("COMMAND_ACK") if ack.command == ARM_DISARM]
    assert _armed(gcs)


@contextmanager
def _silenced_controller(timeout_s: float = 0.5) -> Iterator[tuple[BridgeRig, GroundStation]]:
    """A bridge whose controller answered, then fell silent just now; a ground station on it
    (the reply timeout by default the command line's)."""
    with running_bridge(timeout_s=timeout_s) as rig:
        gcs = GroundStation(rig.gcs_address)
        try:
            gcs.start_heartbeats()
            wait_for(lambda: rig.bridge.rov.health.status == "ok")
            gcs.receive_new("HEARTBEAT")  # the ground station knows where the vehicle is
            rig.link.silent.set()
            yield rig, gcs
        finally:
            gcs.close()


def test_arming_fails_while_the_controller_does_not_answer():
    with _silenced_controller() as (rig, gcs):
        gcs.receive_new(  # a poll failed: before, arming still went through
            "HEARTBEAT", condition=lambda m: m.type == SUBMARINE and m.system_status == CRITICAL
        )
        mark = len(rig.frames())
        assert gcs.arm() == FAILED
        assert "#start!" not in rig.frames_since(mark)
        gcs.receive("STATUSTEXT", condition=lambda m: "Arm refused" in m.text)

        rig.link.silent.clear()
        gcs.receive_new(
            "HEARTBEAT", condition=lambda m: m.type == SUBMARINE and m.system_status == STANDBY
        )
        assert gcs.arm() == ACCEPTED
        rig.wait_frame("#start!", since=mark)


READING_MESSAGES = ("ATTITUDE", "VFR_HUD", "GLOBAL_POSITION_INT", "SCALED_PRESSURE2")


def test_a_silent_controllers_last_reading_is_not_shown_as_current():
    # Before, ATTITUDE, VFR_HUD and GLOBAL_POSITION_INT went on with the last reading under a
    # fresh time_boot_ms: a robot that was diving showed diving at that rate for as long as
    # its controller stayed silent.
    with _silenced_controller(timeout_s=0.2) as (rig, gcs):
        for message_id in (ATTITUDE_ID, SYSTEM_TIME_ID):  # both every 20 ms
            assert gcs.command(SET_MESSAGE_INTERVAL, message_id, 20_000) == ACCEPTED
        gcs.receive_new(
            "HEARTBEAT", condition=lambda m: m.type == SUBMARINE and m.system_status == CRITICAL
        )
        gcs.forget_kept()  # what came before the CRITICAL heartbeat
        for _ in range(10):  # ten periods of telemetry: ten ATTITUDEs were due in them
            gcs.receive("SYSTEM_TIME")
        assert [kind for kind in READING_MESSAGES if gcs.kept(kind)] == []
        assert gcs.command(REQUEST_MESSAGE, ATTITUDE_ID) == TEMPORARILY_REJECTED

        rig.link.silent.clear()  # the controller answers again: so does the telemetry
        gcs.receive("ATTITUDE")
        assert gcs.command(REQUEST_MESSAGE, ATTITUDE_ID) == ACCEPTED


@pytest.mark.realtime  # (a climb rate by the wall clock, of a simulator run in bursts when busy)
def test_the_climb_rate_after_a_silence_is_not_the_one_from_before_it():
    # Before, the climb rate went on averaging from the speed before the silence: a robot
    # stopped meanwhile showed diving at most of its old speed once the controller answered.
    with _silenced_controller(timeout_s=0.2) as (rig, gcs):
        rig.link.silent.clear()
        assert gcs.arm() == ACCEPTED

        def diving_fast(hud: Any) -> bool:
            gcs.send("manual_control", VEHICLE, 0, 0, 0, 0, 0)  # full down
            return bool(hud.climb < -0.3)

        gcs.receive_new("VFR_HUD", condition=diving_fast)
        rig.link.silent.set()
        gcs.receive_new(
            "HEARTBEAT", condition=lambda m: m.type == SUBMARINE and m.system_status == CRITICAL
        )
        assert gcs.command(ARM_DISARM, 0) == ACCEPTED  # (the robot stops)
        gcs.forget_kept()
        rig.link.silent.clear()
        hud = gcs.receive("VFR_HUD")  # the first since: from readings after the silence
        assert hud.climb > -0.15


def test_arming_fails_as_soon_as_the_controller_goes_silent():
    # Before any poll has failed: the pre-arm query finds the silence (before, the bridge armed
    # a controller that had stopped answering until a poll timed out, 1.5-2 s later).
    with _silenced_controller() as (rig, gcs):
        mark = len(rig.frames())
        assert gcs.arm() == FAILED
        assert "#start!" not in rig.frames_since(mark)
        assert "#qd!" in rig.frames_since(mark)  # the pre-arm query
        gcs.receive("STATUSTEXT", condition=lambda m: "Arm refused" in m.text)


def test_arming_an_armed_vehicle_asks_nothing_and_holds_up_no_disarm():
    # Before, a second ARM sent a pre-arm query and, from a controller whose replies no longer
    # came back, waited a reply timeout and its retries before the disarm after it was read.
    with _silenced_controller() as (rig, gcs):
        rig.link.silent.clear()
        assert gcs.arm() == ACCEPTED
        rig.link.silent.set()
        mark = len(rig.frames())
        gcs.send("command_long", VEHICLE, 1, ARM_DISARM, 0, 1.0, *[0.0] * 6)  # ARM again
        gcs.send("command_long", VEHICLE, 1, ARM_DISARM, 0, 0.0, *[0.0] * 6)  # DISARM
        acks = [gcs.receive("COMMAND_ACK", condition=lambda m: m.command == ARM_DISARM)]
        acks.append(gcs.receive("COMMAND_ACK", condition=lambda m: m.command == ARM_DISARM))
        assert [ack.result for ack in acks] == [ACCEPTED, ACCEPTED]
        sent = rig.frames_since(mark)
        assert "#stop!" in sent
        assert "#qd!" not in sent[: sent.index("#stop!")]
        assert "#start!" not in sent


def _long_statustext(gcs: GroundStation, first: Callable[[Any], bool]) -> str:
    """A STATUSTEXT joined from its chunks (MAVLink 2 ``id``, ``chunk_seq``), as a GCS does."""
    head = gcs.receive("STATUSTEXT", condition=first)
    chunks = [head]
    while head.id != 0 and len(chunks[-1].text) == 50:  # a shorter chunk is the last
        chunks.append(
            gcs.receive(
                "STATUSTEXT",
                condition=lambda m: m.id == head.id and m.chunk_seq == len(chunks),
            )
        )
    return "".join(chunk.text for chunk in chunks)


def test_a_long_refusal_comes_whole_in_chunks_naming_the_value(rig: BridgeRig, gcs: GroundStation):
    gcs.send("param_set", VEHICLE, 1, b"RL_DEPTH_ZERO", 1e30, 6)
    text = _long_statustext(gcs, lambda m: m.text.startswith("RL_DEPTH_ZERO"))
    assert text == "RL_DEPTH_ZERO must be an integer in 0-1024, got 1e+30"
    gcs.send("param_set", VEHICLE, 1, b"RL_DEPTH_P", 120.0, 6)  # a short one: one message, id 0
    short = gcs.receive("STATUSTEXT", condition=lambda m: m.text.startswith("RL_DEPTH_P"))
    assert (short.text, short.id) == ("RL_DEPTH_P must be an integer in 0-99, got 120", 0)


def test_after_a_controller_reset_the_parameters_and_the_mode_are_sent_again():
    # A reset brings the controller back with its configured defaults, in depth mode (P21, P9):
    # a maximum PWM of 100 became 255 again unseen, and MANUAL's throttle (#mvs) was dropped.
    with _silenced_controller() as (rig, gcs):
        rig.link.silent.clear()
        controller = rig.port.robot.controller
        gcs.send("param_set", VEHICLE, 1, b"RL_MAX_PWM", 100.0, 6)
        wait_for(lambda: controller.state().max_pwm == 100)
        assert gcs.arm() == ACCEPTED
        rig.link.silent.set()  # the controller resets: silent while it boots
        controller.reset()
        gcs.receive("STATUSTEXT", condition=lambda m: "may have reset" in m.text)
        rig.link.silent.clear()
        gcs.receive("STATUSTEXT", condition=lambda m: "sent again" in m.text)
        state = controller.state()
        assert (state.max_pwm, state.vertical_mode) == (100, VerticalMode.DIRECT)
        assert gcs.arm() == ACCEPTED
        gcs.send("manual_control", VEHICLE, 0, 0, 1000, 0, 0)  # full up, in MANUAL
        wait_for(lambda: controller.state().vertical_thrust_percent == 100)


NO_CHANGE = 65535


def _rc(gcs: GroundStation, *channels: int, target: int = VEHICLE) -> None:
    """RC_CHANNELS_OVERRIDE of channels 1… (the rest released), as MAVProxy's ``rc`` sends it."""
    padded = [*channels, *[0] * (18 - len(channels))]
    gcs.send("rc_channels_override", target, 1, *padded)


def _motion(rig: BridgeRig, since: int) -> list[str]:
    return [f for f in rig.frames_since(since) if f.startswith(("#th", "#mvs", "#mvd."))]


def test_rc_override_flies_ardusubs_channels_and_a_release_is_neutral(
    rig: BridgeRig, gcs: GroundStation
):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    # Pitch, roll and yaw (1, 2, 4) have no command; throttle 3 up a quarter, forward 5 full.
    _rc(gcs, 1900, 1100, 1600, 1900, 1900, 1500)
    rig.wait_frame("#mvs.+25!", since=mark)
    rig.wait_frame("#th.0.100!", since=mark)
    moved = len(rig.frames())
    _rc(gcs, NO_CHANGE, NO_CHANGE, NO_CHANGE, NO_CHANGE, NO_CHANGE, 1100)  # lateral full left
    rig.wait_frame("#th.315.100!", since=moved)  # forward kept: UINT16_MAX is no change
    _rc(gcs, NO_CHANGE, NO_CHANGE, 0, NO_CHANGE, 0, 0)  # all three released
    rig.wait_frame("#mvs.+0!", since=moved)
    rig.wait_frame("#th.315.0!", since=moved)
    assert _motion(rig, mark) == [
        "#th.0.100!",
        "#mvs.+25!",
        "#th.315.100!",
        "#th.315.0!",
        "#mvs.+0!",
    ]


def test_rc_override_is_only_the_pilots_and_only_when_armed(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    mark = len(rig.frames())
    _rc(gcs, 1500, 1500, 1900, 1500, 1900)  # disarmed: the controller would drop it (P7)
    _served_since(gcs)
    assert _motion(rig, mark) == []
    assert gcs.arm() == ACCEPTED
    armed = len(rig.frames())
    gcs.connection.mav.srcSystem = 254  # a second ground station (not SYSID_MYGCS)
    try:
        _rc(gcs, 1500, 1500, 1900, 1500, 1900)
    finally:
        gcs.connection.mav.srcSystem = 255
    gcs.receive("STATUSTEXT", condition=lambda m: "GCS 254 ignored" in m.text)
    _served_since(gcs)
    assert _motion(rig, armed) == []


def _thrust(rig: BridgeRig, since: int) -> list[str]:
    """Motion frames that ask for thrust (zero thrust left out)."""
    return [f for f in _motion(rig, since) if f not in {"#mvs.+0!"} and not f.endswith(".0!")]


def _said(gcs: GroundStation, text: str) -> None:
    gcs.receive("STATUSTEXT", condition=lambda m: text in m.text)


def test_an_rc_override_set_while_disarmed_is_held_at_neutral_once_armed(
    rig: BridgeRig, gcs: GroundStation
):
    gcs.start_heartbeats()
    _rc(gcs, 1500, 1500, 1600, 1500, 1900)  # disarmed: throttle up, full ahead
    _served_since(gcs)
    assert gcs.arm() == ACCEPTED
    armed = len(rig.frames())
    for _ in range(3):  # repeated, as MAVProxy repeats its overrides
        _rc(gcs, 1500, 1500, 1600, 1500, 1900)
    _said(gcs, "RC 3 held: return to neutral")
    _said(gcs, "RC 5 held: return to neutral")
    _served_since(gcs)
    assert _thrust(rig, armed) == []  # before: #th.0.100!, #mvs.+25! at once
    _rc(gcs, 1500, 1500, 1530, 1500, 0)  # 3 within 40 µs of neutral, 5 released
    _rc(gcs, 1500, 1500, 1600, 1500, 1900)  # a fresh input
    rig.wait_frame("#th.0.100!", since=armed)
    rig.wait_frame("#mvs.+25!", since=armed)


def test_an_rc_override_left_from_before_a_disarm_is_held_after_re_arming(
    rig: BridgeRig, gcs: GroundStation
):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    _rc(gcs, 1500, 1500, 1500, 1500, 1500, 1900)  # full right
    rig.wait_frame("#th.90.100!", since=mark)
    assert gcs.command(ARM_DISARM, 0) == ACCEPTED
    rig.wait_frame("#stop!", since=mark)
    assert gcs.arm() == ACCEPTED
    re_armed = len(rig.frames())
    _rc(gcs, 1500, 1500, 1500, 1500, 1500, 1900)  # still set
    _said(gcs, "RC 6 held: return to neutral")
    _served_since(gcs)
    assert _thrust(rig, re_armed) == []
    _rc(gcs, 1500, 1500, 1500, 1500, 1500, 1500)
    _rc(gcs, 1500, 1500, 1500, 1500, 1500, 1700)
    rig.wait_frame("#th.90.50!", since=re_armed)


def test_a_joystick_off_centre_as_it_arms_is_held_until_centred(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    mark = len(rig.frames())
    gcs.send("manual_control", VEHICLE, 800, 0, 500, 0, 1 << 6)  # BTN6 arms, stick ahead
    rig.wait_frame("#start!", since=mark)
    gcs.send("manual_control", VEHICLE, 800, 0, 500, 0, 1 << 6)
    _said(gcs, "Joystick x held: return to centre")
    _served_since(gcs)
    assert _thrust(rig, mark) == []
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)  # centred
    gcs.send("manual_control", VEHICLE, 800, 0, 500, 0, 0)
    rig.wait_frame("#th.0.80!", since=mark)


NEW_PILOT = 254


@pytest.mark.parametrize(
    ("off_centre", "centred", "said", "driven"),
    [
        (
            ("manual_control", VEHICLE, 800, 0, 500, 0, 0),
            ("manual_control", VEHICLE, 0, 0, 500, 0, 0),
            "Joystick x held: return to centre",
            "#th.0.80!",
        ),
        (
            ("rc_channels_override", VEHICLE, 1, 1500, 1500, 1500, 1500, 1900, *[0] * 13),
            ("rc_channels_override", VEHICLE, 1, 1500, 1500, 1500, 1500, 1500, *[0] * 13),
            "RC 5 held: return to neutral",
            "#th.0.100!",
        ),
    ],
    ids=["joystick", "rc_override"],
)
def test_a_new_pilots_input_off_centre_is_held_until_centred(
    rig: BridgeRig,
    gcs: GroundStation,
    off_centre: tuple[Any, ...],
    centred: tuple[Any, ...],
    said: str,
    driven: str,
):
    # The pilot's ground station changes (SYSID_MYGCS) while armed: the new pilot's stick or
    # override, off centre all along while ignored, once drove the robot with its first message.
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    gcs.send("param_set", VEHICLE, 1, b"SYSID_MYGCS", float(NEW_PILOT), 6)
    gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "SYSID_MYGCS")
    changed = len(rig.frames())
    gcs.connection.mav.srcSystem = NEW_PILOT  # the new pilot's ground station (and heartbeat)
    gcs.send(*off_centre)
    gcs.send(*off_centre)  # repeated, as a joystick or MAVProxy's overrides are
    _said(gcs, said)
    _served_since(gcs)
    assert _thrust(rig, changed) == []
    gcs.send(*centred)
    gcs.send(*off_centre)  # a fresh input
    rig.wait_frame(driven, since=changed)


BTN_MODE_DEPTH_HOLD, BTN_ARM = 1 << 2, 1 << 6  # ArduSub's default mapping


@pytest.mark.parametrize(
    ("armed", "held", "acted"),
    [(False, BTN_ARM, "#start!"), (True, BTN_MODE_DEPTH_HOLD, "#mvdirect.0!")],
    ids=["arm_button_disarmed", "mode_button_armed"],
)
def test_a_button_the_new_pilot_holds_at_the_hand_over_needs_a_release(
    rig: BridgeRig, gcs: GroundStation, armed: bool, held: int, acted: str
):
    # The new pilot's button, held while its joystick was ignored, once counted as a press with
    # its first message: an arm button armed the vehicle, a mode button changed the mode.
    gcs.start_heartbeats()
    if armed:
        assert gcs.arm() == ACCEPTED
    gcs.send("param_set", VEHICLE, 1, b"SYSID_MYGCS", float(NEW_PILOT), 6)
    gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "SYSID_MYGCS")
    changed = len(rig.frames())
    gcs.connection.mav.srcSystem = NEW_PILOT
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, held)
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, held)  # repeated, as a joystick's are
    _said(gcs, f"Button {held.bit_length() - 1} held: release it")
    _served_since(gcs)
    assert acted not in rig.frames_since(changed)
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0)  # released ...
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, held)  # ... and pressed: a press
    rig.wait_frame(acted, since=changed)


def test_rc_override_that_stops_coming_is_zeroed_as_a_stale_joystick(
    rig: BridgeRig, gcs: GroundStation
):
    gcs.start_heartbeats()
    assert gcs.arm() == ACCEPTED
    mark = len(rig.frames())
    # Taken before the send: the bridge cannot have the input earlier (taken after the frames
    # were seen, a loaded machine's delay in seeing them came off the 1 s and failed the test).
    last_input_s = time.monotonic()
    _rc(gcs, 1500, 1500, 1100, 1500, 1500, 1900)  # right, full down
    rig.wait_frame("#th.90.100!", since=mark)
    rig.wait_frame("#mvs.-100!", since=mark)
    rig.wait_frame("#th.90.0!", since=mark)
    assert time.monotonic() - last_input_s >= 0.9
    rig.wait_frame("#mvs.+0!", since=mark)
    assert "#stop!" not in rig.frames_since(mark)
    # Input that resumes after the silence starts from neutral: a channel left unchanged is not
    # the stale value of before.
    resumed = len(rig.frames())
    _rc(gcs, *[NO_CHANGE] * 5, 1700)
    rig.wait_frame("#th.90.50!", since=resumed)
    assert "#mvs.-100!" not in rig.frames_since(resumed)


def test_buttons_16_to_31_come_in_buttons2(rig: BridgeRig, gcs: GroundStation):
    gcs.start_heartbeats()
    gcs.send("param_set", VEHICLE, 1, b"BTN16_FUNCTION", 3.0, 6)  # arm
    gcs.send("param_set", VEHICLE, 1, b"BTN31_FUNCTION", 4.0, 6)  # disarm
    gcs.receive("PARAM_VALUE", condition=lambda m: m.param_id == "BTN31_FUNCTION")
    mark = len(rig.frames())
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0, 1)  # buttons2 bit 0: button 16
    rig.wait_frame("#start!", since=mark)
    gcs.send("manual_control", VEHICLE, 0, 0, 500, 0, 0, 1 << 15)  # button 31
    rig.wait_frame("#stop!", since=mark)


@pytest.mark.realtime
def test_a_controller_that_hears_but_stops_answering_is_stopped_while_flown_in_manual():
    # Its TX wire broke: the controller obeys every frame and answers none. A ground station
    # flying MANUAL goes on sending its joystick (fresh input, heartbeats beating): the bridge
    # stops the robot a bounded time after the replies stop, and says why.
    with _silenced_controller() as (rig, gcs):
        rig.link.silent.clear()
        controller = rig.port.robot.controller
        assert gcs.arm() == ACCEPTED
        gcs.send("manual_control", VEHICLE, 0, 1000, 500, 0, 0)  # right, full
        wait_for(lambda: controller.state().power_percent == 100)
        mark = len(rig.frames())
        silent_at_s = time.monotonic()
        rig.link.silent.set()

        def stopped() -> bool:
            gcs.send("manual_control", VEHICLE, 0, 1000, 500, 0, 0)  # the pilot flies on
            return "#stop!" in rig.frames_since(mark)

        wait_for(stopped, timeout_s=5.0)
        assert time.monotonic() - silent_at_s < 2.5  # two reply timeouts of 0.5 s, and margin
        wait_for(lambda: controller.state().locked)  # it heard the #stop!: every output zero
        assert controller.state().power_percent == 0
        gcs.receive("STATUSTEXT", condition=lambda m: "controller silent" in m.text)
        after = rig.frames_since(mark)
        assert not [f for f in after[after.index("#stop!") :] if f.startswith("#th.90.100")]


def test_a_suspected_reset_of_a_disarmed_vehicle_does_not_say_disarmed():
    # Before, the lock the reset had just made unknown was read as "may have been armed": a
    # vehicle never armed was told "Disarmed: the controller may have reset", and #stop! sent.
    with _silenced_controller() as (rig, gcs):
        gcs.forget_kept()
        mark = len(rig.frames())
        wait_for(lambda: rig.bridge.rov.client.counters.resets_suspected >= 1)
        rig.link.silent.clear()  # it answers: its settings go again, said after the reset's
        gcs.receive("STATUSTEXT", condition=lambda m: "sent again" in m.text)
        said = [m.text for m in gcs.kept("STATUSTEXT")]
        assert not [text for text in said if "Disarmed" in text], said
        assert "#stop!" not in rig.frames_since(mark)
