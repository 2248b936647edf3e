"""The MAVLink bridge's decisions, without sockets: parameters, joystick, failsafe, rates, units."""

from __future__ import annotations

import math
import struct
from types import SimpleNamespace

import pytest

from rovlink.bridges.mavlink.command_handling import Result, handle_command
from rovlink.bridges.mavlink.endpoint import is_addressed_to
from rovlink.bridges.mavlink.failsafe import GCS_TIMEOUT_S, GcsWatchdog
from rovlink.bridges.mavlink.modes import ButtonFunction, FlightMode
from rovlink.bridges.mavlink.parameters import (
    ParameterError,
    ParameterTable,
    read_parameter_file,
)
from rovlink.bridges.mavlink.pilot_input import (
    AXIS_UNUSED,
    INPUT_STALE_S,
    PilotInput,
    PilotOutput,
    all_buttons,
    horizontal,
    vertical_thrust_percent,
)
from rovlink.bridges.mavlink.rc_override import CHANNEL_NO_CHANGE, RcOverride
from rovlink.bridges.mavlink.telemetry_messages import (
    STATUSTEXT_CHARS,
    TelemetryMessages,
    statustext_chunks,
)
from rovlink.bridges.mavlink.telemetry_schedule import MAX_RATE_HZ, TelemetrySchedule
from rovlink.bridges.mavlink.vehicle_state import (
    SURFACE_PRESSURE_HPA,
    WATER_HPA_PER_M,
    VehicleState,
)
from rovlink.client.sensors import Sensors
from rovlink.piloting.commanded import CommandedState
from rovlink.protocol import Command, lookup

#: 1e30 as PARAM_SET carries it (a float32): 1.0000000150474662e+30.
FLOAT32_1E30 = struct.unpack("<f", struct.pack("<f", 1e30))[0]

# -- parameters ------------------------------------------------------------------------------


def test_parameter_ranges_come_from_the_command_table():
    table = ParameterTable()
    for parameter in table.parameters:
        if parameter.command_name is not None:
            (argument,) = lookup(parameter.command_name).arguments
            assert (parameter.minimum, parameter.maximum) == (argument.minimum, argument.maximum)
    assert str(table.set("RL_MAX_PWM", 200)) == "#mgmp.200!"
    assert str(table.set("RL_DEPTH_D", 7)) == "#mvpidd.7!"
    assert str(table.set("RL_DEPTH_K", 10000)) == "#sdk.10000!"


@pytest.mark.parametrize(
    ("name", "value", "message"),
    [
        ("RL_DEPTH_P", 100, "RL_DEPTH_P must be an integer in 0–99, got 100"),
        ("RL_DEPTH_P", 1.5, "RL_DEPTH_P must be an integer in 0–99, got 1.5"),
        ("RL_DEPTH_P", math.nan, "RL_DEPTH_P must be an integer in 0–99, got nan"),
        ("RL_MAX_PWM", -1, "RL_MAX_PWM must be an integer in 0–255, got -1"),
        # Huge whole floats are not written as their 31 digits (cut to "got 10" on the air).
        ("RL_DEPTH_ZERO", 1e30, "RL_DEPTH_ZERO must be an integer in 0–1024, got 1e+30"),
        ("RL_DEPTH_ZERO", FLOAT32_1E30, "RL_DEPTH_ZERO must be an integer in 0–1024, got 1e+30"),
        ("RL_DEPTH_P", -math.inf, "RL_DEPTH_P must be an integer in 0–99, got -inf"),
        ("NO_SUCH", 1, "no parameter 'NO_SUCH'"),
    ],
)
def test_a_refused_value_changes_nothing(name: str, value: float, message: str):
    table = ParameterTable({"RL_DEPTH_P": 40, "RL_MAX_PWM": 255})
    with pytest.raises(ParameterError) as caught:
        table.set(name, value)
    assert str(caught.value) == message
    assert table.value("RL_DEPTH_P") == 40
    assert table.value("RL_MAX_PWM") == 255


def test_button_functions_default_to_ardusub_and_refuse_what_cannot_be_done():
    table = ParameterTable()
    assert table.button_function(6) is ButtonFunction.ARM
    assert table.button_function(0) is ButtonFunction.NONE
    assert table.set("BTN0_FUNCTION", 7) is None  # the bridge's own: no frame
    assert table.button_function(0) is ButtonFunction.MODE_DEPTH_HOLD
    with pytest.raises(ParameterError, match="function 6 is not supported"):
        table.set("BTN0_FUNCTION", 6)  # STABILIZE: no attitude control


def test_the_pilots_ground_station_is_ardusubs_sysid_mygcs():
    table = ParameterTable()
    assert table.pilot_system == 255  # QGroundControl's, MAVProxy's and pymavlink's own
    assert table.set("SYSID_MYGCS", 200) is None  # the bridge's own: no frame
    assert table.pilot_system == 200
    with pytest.raises(ParameterError, match="SYSID_MYGCS must be an integer in 1–255, got 0"):
        table.set("SYSID_MYGCS", 0)


def test_a_parameter_file_is_read_and_checked_with_line_numbers():
    values = read_parameter_file("# saved\nRL_DEPTH_P 33\nRL_MAX_PWM,200.0\n\n", "robot.param")
    assert values == {"RL_DEPTH_P": 33, "RL_MAX_PWM": 200}
    # Only what the file sets is sent: a calibration it does not mention is left alone.
    assert [str(c) for c in ParameterTable(values).commands(values)] == ["#mvpdp.33!", "#mgmp.200!"]
    with pytest.raises(ParameterError, match=r"robot.param:2: RL_DEPTH_I must be .* got 500"):
        read_parameter_file("RL_DEPTH_P 1\nRL_DEPTH_I 500\n", "robot.param")
    with pytest.raises(ParameterError, match=r"robot.param:1: RL_DEPTH_P: not a number: 'x'"):
        read_parameter_file("RL_DEPTH_P x\n", "robot.param")
    with pytest.raises(ParameterError, match=r"robot.param:1: expected NAME VALUE"):
        read_parameter_file("RL_DEPTH_P\n", "robot.param")


#: A parameter file as QGroundControl saves it (its header, tab-separated columns).
QGC_FILE = """\
# Onboard parameters for Vehicle 1
#
# Stack: ArduPilot
# Vehicle: Sub
#
# Vehicle-Id Component-Id Name Value Type
1\t1\tBTN3_FUNCTION\t7\t6
1\t1\tRL_DEPTH_P\t33\t6
1\t1\tRL_MAX_PWM\t200.000000000000000000\t9
"""
#: As MAVProxy's ``param save`` writes it.
MAVPROXY_FILE = "BTN3_FUNCTION    7.000000\nRL_DEPTH_P       33.000000\nRL_MAX_PWM  200  # capped\n"


@pytest.mark.parametrize("text", [QGC_FILE, MAVPROXY_FILE], ids=["QGroundControl", "MAVProxy"])
def test_parameter_files_as_ground_stations_save_them(text: str):
    values = read_parameter_file(text, "robot.params")
    assert values == {"BTN3_FUNCTION": 7, "RL_DEPTH_P": 33, "RL_MAX_PWM": 200}


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("1\t1\tRL_DEPTH_P\t150\t6", "RL_DEPTH_P must be an integer in 0–99, got 150"),
        ("1\t100\tRL_DEPTH_P\t33\t6", "component id must be 1 (the autopilot's"),
        ("x\t1\tRL_DEPTH_P\t33\t6", "vehicle id must be an integer in 1–255, got 'x'"),
        ("1\t1\tRL_DEPTH_P\t33\t11", "type must be an integer in 1–10, got '11'"),
        ("1\t1\tRL_DEPTH_P\tx\t6", "RL_DEPTH_P: not a number: 'x'"),
        ("1\t1\tRL_DEPTH_P\t33", "expected NAME VALUE (MAVProxy, Mission Planner: NAME,VALUE) or"),
    ],
)
def test_a_bad_qgroundcontrol_line_is_named_with_its_number(line: str, message: str):
    with pytest.raises(ParameterError) as caught:
        read_parameter_file(f"# header\n1\t1\tRL_DEPTH_I\t5\t6\n{line}\n", "robot.params")
    assert str(caught.value).startswith(f"robot.params:3: {message}")


# -- the joystick ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("x", "y", "expected"),
    [(1000, 0, (0, 100)), (0, 1000, (90, 100)), (-500, 0, (180, 50)), (707, -707, (315, 100))],
)
def test_the_stick_is_a_direction_and_a_power(x: int, y: int, expected: tuple[int, int]):
    assert horizontal(x, y) == expected


def test_throttle_is_clamped_vertical_thrust():
    assert vertical_thrust_percent(0) == -100
    assert vertical_thrust_percent(1000) == 100
    assert vertical_thrust_percent(510) == 2


def _drive(pilot: PilotInput, x: int, y: int, z: int, now_s: float, **kwargs: object) -> list[str]:
    settings: dict[str, object] = {"mode": FlightMode.MANUAL, "armed": True, "buttons": 0}
    settings.update(kwargs)
    output = pilot.manual_control(x, y, z, now_s=now_s, **settings)  # type: ignore[arg-type]
    return [str(command) for command in output.commands]


def test_only_changes_are_sent_and_yaw_never():
    pilot = PilotInput(ParameterTable())
    assert _drive(pilot, 0, 500, 500, 0.0) == ["#th.90.50!"]
    assert _drive(pilot, 0, 500, 500, 0.02) == []
    assert _drive(pilot, 0, 0, 500, 0.04) == ["#th.90.0!"]
    assert _drive(pilot, 0, 0, 500, 0.06) == []  # still zero: nothing
    assert _drive(pilot, AXIS_UNUSED, AXIS_UNUSED, AXIS_UNUSED, 0.08) == []


def test_nothing_is_sent_while_disarmed_but_buttons_still_count():
    pilot = PilotInput(ParameterTable())
    output = pilot.manual_control(
        1000, 0, 1000, 1 << 6, mode=FlightMode.MANUAL, armed=False, now_s=0.0
    )
    assert output.commands == ()
    assert output.pressed == (ButtonFunction.ARM,)
    held = pilot.manual_control(0, 0, 500, 1 << 6, mode=FlightMode.MANUAL, armed=False, now_s=0.1)
    assert held.pressed == ()  # once per press, not per message


def _pressed(pilot: PilotInput, buttons: int | None, now_s: float) -> tuple[ButtonFunction, ...]:
    output = pilot.manual_control(
        0, 0, 500, buttons, mode=FlightMode.MANUAL, armed=False, now_s=now_s
    )
    return output.pressed


def test_buttons_16_to_31_carry_out_their_functions_and_none_by_default():
    table = ParameterTable()
    assert table.value("BTN16_FUNCTION") == table.value("BTN31_FUNCTION") == 0
    table.set("BTN16_FUNCTION", int(ButtonFunction.ARM))
    table.set("BTN31_FUNCTION", int(ButtonFunction.DISARM))
    pilot = PilotInput(table)
    assert _pressed(pilot, all_buttons(0, 1), 0.0) == (ButtonFunction.ARM,)
    both = _pressed(pilot, all_buttons(0, 1 | 1 << 15), 0.1)
    assert both == (ButtonFunction.DISARM,)  # 16 still held: once per press
    assert all_buttons(0xFFFF, 0xFFFF) == 0xFFFF_FFFF


def test_input_without_buttons_leaves_the_held_ones_as_they_were():
    pilot = PilotInput(ParameterTable())
    assert _pressed(pilot, 1 << 6, 0.0) == (ButtonFunction.ARM,)
    assert _pressed(pilot, None, 0.1) == ()
    assert _pressed(pilot, 1 << 6, 0.2) == ()  # still held: no new press


@pytest.mark.parametrize(
    ("pulse_us", "deflection"),
    [(1100, -1000), (1300, -500), (1500, 0), (1700, 500), (1900, 1000), (900, -1000), (2100, 1000)],
)
def test_rc_pulses_become_the_stick(pulse_us: int, deflection: int):
    rc = RcOverride(stale_after_s=INPUT_STALE_S)
    x, y, z = rc.update([1500, 1500, pulse_us, 1500, pulse_us, pulse_us, 1500, 1500], now_s=0.0)
    assert (x, y) == (deflection, deflection)
    assert z == (deflection + 1000) // 2
    assert vertical_thrust_percent(z) == deflection // 10


def test_rc_release_is_neutral_and_no_change_keeps_the_channel():
    rc = RcOverride(stale_after_s=INPUT_STALE_S)
    assert rc.update([1900, 1100, 1900, 1900, 1900, 1900, 0, 0], now_s=0.0) == (1000, 1000, 1000)
    keep = [CHANNEL_NO_CHANGE] * 8
    assert rc.update(keep, now_s=0.1) == (1000, 1000, 1000)
    assert rc.update([*keep[:4], 0, *keep[5:]], now_s=0.2) == (0, 1000, 1000)  # 5 released
    assert rc.update([0] * 8, now_s=0.3) == (0, 0, 500)
    rc.update([1500, 1500, 1900, 1500, 1900, 1900, 0, 0], now_s=0.4)
    assert rc.update(keep, now_s=0.4 + INPUT_STALE_S - 0.01) == (1000, 1000, 1000)
    assert rc.update(keep, now_s=0.4 + 2 * INPUT_STALE_S) == (0, 0, 500)  # stale: released


def _held(pilot: PilotInput, x: int, y: int, z: int, now_s: float) -> tuple[str, ...]:
    output = pilot.manual_control(x, y, z, 0, mode=FlightMode.MANUAL, armed=True, now_s=now_s)
    return output.newly_held


def test_an_axis_off_centre_at_arming_is_held_at_neutral_until_centred():
    pilot = PilotInput(ParameterTable())
    _drive(pilot, 1000, 0, 800, 0.0, armed=False)  # held over while disarmed
    pilot.hold_off_centre_axes()  # armed
    assert _held(pilot, 1000, 0, 800, 0.1) == ("x", "z")  # said once each ...
    assert _drive(pilot, 1000, 0, 800, 0.2) == []
    assert _held(pilot, 1000, 0, 800, 0.3) == ()  # ... not again
    assert _drive(pilot, 100, 0, 800, 0.4) == ["#th.0.10!"]  # x centred (the band's edge)
    assert _drive(pilot, 1000, 0, 800, 0.5) == ["#th.0.100!"]  # x free, z still held
    assert _drive(pilot, 1000, 0, 550, 0.6) == ["#mvs.+10!"]  # z within 50 of 500: free
    assert _drive(pilot, 1000, 0, 1000, 0.7) == ["#mvs.+100!"]
    pilot.hold_off_centre_axes()  # re-armed with the stick where it is: held again
    assert _held(pilot, 1000, 0, 1000, 0.8) == ("x", "z")


def test_an_axis_centred_at_arming_is_not_held():
    pilot = PilotInput(ParameterTable())
    _drive(pilot, 1000, 0, 500, 0.0, armed=False)
    _drive(pilot, 0, 100, 450, 0.1, armed=False)  # within the band: centred
    pilot.hold_off_centre_axes()
    assert _drive(pilot, 0, -1000, 0, 0.2) == ["#th.270.100!", "#mvs.-100!"]


def test_an_axis_just_beyond_the_band_at_arming_is_held():
    pilot = PilotInput(ParameterTable())
    _drive(pilot, 0, -101, 449, 0.0, armed=False)
    pilot.hold_off_centre_axes()
    assert _held(pilot, 0, -1000, 0, 0.1) == ("y", "z")


def test_a_new_pilots_first_input_armed_has_its_axes_off_centre_held():
    pilot = PilotInput(ParameterTable())
    assert _drive(pilot, 1000, 0, 500, 0.0) == ["#th.0.100!"]  # the pilot of before drives
    pilot.new_pilot()  # SYSID_MYGCS changed while armed
    output = pilot.manual_control(0, 800, 700, 0, mode=FlightMode.MANUAL, armed=True, now_s=0.1)
    assert output.newly_held == ("y", "z")
    assert [str(command) for command in output.commands] == ["#th.0.0!"]  # neutral: stopped
    assert _held(pilot, 0, 800, 700, 0.2) == ()  # said once; the next input is no first one
    assert _drive(pilot, 0, 0, 500, 0.3) == []  # centred
    assert _drive(pilot, 0, 800, 700, 0.4) == ["#th.90.80!", "#mvs.+40!"]


def test_a_new_pilots_stick_disarmed_is_held_at_arming_and_a_centred_one_drives():
    pilot = PilotInput(ParameterTable())
    pilot.new_pilot()
    _drive(pilot, 0, 800, 500, 0.0, armed=False)  # the new pilot's stick, disarmed
    pilot.hold_off_centre_axes()  # armed: held as any stick at arming
    assert _held(pilot, 0, 800, 500, 0.1) == ("y",)
    pilot.new_pilot()  # armed, a first input centred: nothing held
    assert _drive(pilot, 0, 0, 500, 0.2) == []
    assert _drive(pilot, 1000, 0, 500, 0.3) == ["#th.0.100!"]


def _buttons(pilot: PilotInput, buttons: int | None, now_s: float, *, armed: bool) -> PilotOutput:
    return pilot.manual_control(
        0, 0, 500, buttons, mode=FlightMode.MANUAL, armed=armed, now_s=now_s
    )


def test_a_new_pilots_held_buttons_are_no_press_until_released():
    pilot = PilotInput(ParameterTable())
    pilot.new_pilot()
    assert _buttons(pilot, None, 0.0, armed=False).held_buttons == ()  # an override: no buttons
    first = _buttons(pilot, 1 << 6 | 1 << 9, 0.1, armed=False)  # BTN6 arms; BTN9 has no function
    assert (first.pressed, first.held_buttons) == ((), (6,))
    again = _buttons(pilot, 1 << 6, 0.2, armed=False)
    assert (again.pressed, again.held_buttons) == ((), ())  # said once
    assert _buttons(pilot, 0, 0.3, armed=False).pressed == ()
    assert _buttons(pilot, 1 << 6, 0.4, armed=False).pressed == (ButtonFunction.ARM,)


def test_a_button_held_at_arming_was_pressed_once_before_it():
    pilot = PilotInput(ParameterTable())
    assert _buttons(pilot, 1 << 2, 0.0, armed=False).pressed == (ButtonFunction.MODE_DEPTH_HOLD,)
    pilot.hold_off_centre_axes()  # armed, the button still held: no second press
    assert _buttons(pilot, 1 << 2, 0.1, armed=True).pressed == ()


def test_rc_release_puts_every_channel_back_to_neutral():
    rc = RcOverride(stale_after_s=INPUT_STALE_S)
    rc.update([1500, 1500, 1900, 1500, 1900, 1100, 0, 0], now_s=0.0)
    rc.release()  # another ground station flies: its overrides start from neutral
    assert rc.update([CHANNEL_NO_CHANGE] * 8, now_s=0.1) == (0, 0, 500)


@pytest.mark.parametrize(("pulse_us", "held"), [(1540, False), (1541, True), (1459, True)])
def test_an_rc_channel_counts_as_neutral_within_40_us(pulse_us: int, held: bool):
    rc = RcOverride(stale_after_s=INPUT_STALE_S)
    pilot = PilotInput(ParameterTable())
    x, y, z = rc.update([0, 0, 0, 0, pulse_us, 0, 0, 0], now_s=0.0)
    _drive(pilot, x, y, z, 0.0, armed=False)
    pilot.hold_off_centre_axes()
    x, y, z = rc.update([0, 0, 0, 0, 1900, 0, 0, 0], now_s=0.1)
    assert _held(pilot, x, y, z, 0.1) == (("x",) if held else ())


def test_stale_input_expires_once_after_one_second():
    pilot = PilotInput(ParameterTable())
    _drive(pilot, 1000, 0, 1000, 0.0)
    # P23 names the time: 1 s of stale MANUAL_CONTROL (written out, not the constant).
    assert pilot.expire(0.99) == ()
    assert [str(c) for c in pilot.expire(1.0)] == ["#th.0.0!", "#mvs.+0!"]
    assert pilot.expire(2.0) == ()
    assert _drive(pilot, 1000, 0, 1000, 5.0) == ["#th.0.100!", "#mvs.+100!"]  # input back


def _sent(state: CommandedState, pilot: PilotInput, *frames: Command) -> None:
    """Frames sent: the state as last sent follows them, and the pilot input follows it."""
    for frame in frames:
        state.apply(frame)
        pilot.sync(state)


@pytest.mark.parametrize(
    "repeated", [Command("start"), Command("mvdirect", (1,))], ids=["start", "mvdirect"]
)
def test_a_repeated_start_or_mode_keeps_the_thrust_to_zero(repeated: Command):
    # The controller keeps its set-points across a #start! while unlocked and a #mvdirect to
    # the mode it is in (P7, P9, P11): the stale input and a centred stick must still zero them.
    state, pilot = CommandedState(), PilotInput(ParameterTable())
    _sent(state, pilot, Command("stop"), Command("mvdirect", (1,)), Command("start"))
    driven = pilot.manual_control(1000, 0, 0, 0, mode=FlightMode.MANUAL, armed=True, now_s=0.0)
    _sent(state, pilot, *driven.commands)
    _sent(state, pilot, repeated)
    assert [str(c) for c in pilot.expire(INPUT_STALE_S)] == ["#th.0.0!", "#mvs.+0!"]
    _sent(state, pilot, Command("th", (0, 100)), Command("mvs", (-100,)))
    _sent(state, pilot, repeated)
    assert _drive(pilot, 0, 0, 500, 2.0) == ["#th.0.0!", "#mvs.+0!"]  # the stick centred


def test_stop_and_a_mode_change_zero_what_the_controller_zeroes():
    state, pilot = CommandedState(), PilotInput(ParameterTable())
    _sent(state, pilot, Command("mvdirect", (1,)), Command("start"))
    driven = pilot.manual_control(0, 500, 800, 0, mode=FlightMode.MANUAL, armed=True, now_s=0.0)
    _sent(state, pilot, *driven.commands)  # #th.90.50!, #mvs.+60!
    _sent(state, pilot, Command("mvdirect", (0,)))  # vertical thrust 0, horizontal kept (P9)
    assert [str(c) for c in pilot.expire(INPUT_STALE_S)] == ["#th.90.0!"]
    _sent(state, pilot, Command("th", (90, 50)), Command("stop"))  # everything 0 (P7)
    assert pilot.expire(INPUT_STALE_S + 5) == ()


def test_alt_hold_moves_the_target_with_the_throttle():
    pilot = PilotInput(ParameterTable())
    assert str(pilot.hold(100)) == "#mvd.100!"
    sent = []
    for step in range(11):  # full throttle up for 1 s at 10 Hz: 50 cm shallower
        sent += _drive(pilot, 0, 0, 1000, step * 0.1, mode=FlightMode.ALT_HOLD)
    assert sent[-1] == "#mvd.50!"
    assert not [frame for frame in sent if frame.startswith("#mvs")]
    assert _drive(pilot, 0, 0, 520, 1.2, mode=FlightMode.ALT_HOLD) == []  # inside the deadband


@pytest.mark.parametrize("z", [-1000, 2000, -32768])
def test_a_throttle_beyond_its_range_moves_the_held_depth_no_faster_than_full(z: int):
    # MAVLink's common z is −1000…1000; ArduSub's throttle 0…1000. A z of −1000 in ALT_HOLD once
    # moved the held depth at 150 cm/s, three times the full stick's 50.
    pilot = PilotInput(ParameterTable())
    pilot.hold(500)
    sent = []
    for step in range(11):  # 1 s at 10 Hz
        sent += _drive(pilot, 0, 0, z, step * 0.1, mode=FlightMode.ALT_HOLD)
    assert sent[-1] == ("#mvd.550!" if z < 0 else "#mvd.450!")


# -- the ground-station failsafe ---------------------------------------------------------------


def test_the_gcs_watchdog_trips_at_three_seconds_only_while_armed():
    watchdog = GcsWatchdog()
    watchdog.heartbeat(10.0)
    assert not watchdog.tripped(10.0 + GCS_TIMEOUT_S - 0.001, armed=True)
    assert not watchdog.tripped(20.0, armed=False)
    assert watchdog.tripped(10.0 + GCS_TIMEOUT_S, armed=True)
    assert not watchdog.tripped(30.0, armed=True)  # once per silence
    watchdog.heartbeat(31.0)
    assert watchdog.tripped(34.0, armed=True)


def test_armed_without_any_heartbeat_trips_at_once():
    assert GcsWatchdog().tripped(0.0, armed=True)


# -- telemetry rates ---------------------------------------------------------------------------


def test_rates_follow_streams_and_intervals_within_bounds():
    schedule = TelemetrySchedule(now_s=0.0)
    schedule.set_stream(10, 50.0, now_s=0.0)  # EXTRA1 → ATTITUDE
    assert schedule.rates_hz["ATTITUDE"] == MAX_RATE_HZ
    schedule.set_stream(0, 0.0, now_s=0.0)  # every stream off
    assert schedule.rates_hz["HEARTBEAT"] == 1.0  # never
    assert schedule.rates_hz["SYS_STATUS"] == 0.0
    assert not schedule.set_interval("HEARTBEAT", 0.01, now_s=0.0)
    assert not schedule.set_interval("BATTERY_STATUS", 1.0, now_s=0.0)
    assert schedule.set_interval("VFR_HUD", None, now_s=0.0)  # back to the default
    assert schedule.rates_hz["VFR_HUD"] == 4.0


def test_only_messages_with_readings_set_how_often_the_sensors_are_read():
    schedule = TelemetrySchedule(now_s=0.0)
    assert schedule.fastest_rate_hz() == 4.0  # ATTITUDE, VFR_HUD, GLOBAL_POSITION_INT
    assert schedule.set_interval("SYSTEM_TIME", 1 / MAX_RATE_HZ, now_s=0.0)  # the clock, fast
    assert schedule.fastest_rate_hz() == 4.0  # no reason to poll the serial line faster
    assert schedule.set_interval("SCALED_PRESSURE2", 0.1, now_s=0.0)
    assert schedule.fastest_rate_hz() == 10.0


def test_a_stalled_schedule_does_not_burst():
    schedule = TelemetrySchedule(now_s=0.0)
    schedule.due(0.0)
    assert "HEARTBEAT" in schedule.due(5.0)  # five periods late: sent once
    assert "HEARTBEAT" not in schedule.due(5.01)
    assert "HEARTBEAT" in schedule.due(6.0)


# -- STATUSTEXT ----------------------------------------------------------------------------------


@pytest.mark.parametrize("length", [0, 49, 50, 51, 100, 120])
def test_statustext_chunks_carry_the_whole_text_and_end_short(length: int):
    text = "".join(chr(ord("a") + n % 26) for n in range(length))
    chunks = statustext_chunks(text)
    assert b"".join(chunks).decode() == text
    assert all(len(chunk) == STATUSTEXT_CHARS for chunk in chunks[:-1])
    assert len(chunks[-1]) < STATUSTEXT_CHARS  # a NUL on the air: the last chunk


# -- units -------------------------------------------------------------------------------------


def test_vehicle_state_in_mavlink_units():
    state = VehicleState()
    assert not state.update(Sensors(0, 20, False, 0, 0, 0), now_s=0.0)
    assert state.update(Sensors(100, 70, True, 10, -5, 350), now_s=1.0)  # the leak, once
    assert not state.update(Sensors(100, 70, True, 10, -5, 350), now_s=2.0)
    assert state.altitude_m() == -1.0
    roll, pitch, yaw = state.attitude_rad()
    assert (round(math.degrees(roll)), round(math.degrees(pitch))) == (10, -5)
    assert round(math.degrees(yaw)) == -10
    assert state.climb_cm_s < 0  # it went down
    # (70 − 20) · 200 / 10000 = 1 m of water
    assert state.absolute_pressure_hpa(20, 200) == pytest.approx(
        SURFACE_PRESSURE_HPA + WATER_HPA_PER_M
    )


# -- commands ----------------------------------------------------------------------------------


class _Actions:
    """Records what the commands asked the vehicle to do."""

    def __init__(self) -> None:
        self.done: list[str] = []

    async def arm(self) -> Result:
        self.done.append("arm")
        return Result.ACCEPTED

    async def disarm(self, reason: str) -> Result:
        self.done.append("disarm")
        return Result.ACCEPTED

    async def set_mode(self, mode: FlightMode) -> Result:
        self.done.append(mode.name)
        return Result.ACCEPTED

    async def gripper(self, *, close: bool) -> Result:
        self.done.append("close" if close else "open")
        return Result.ACCEPTED

    def request_message(self, message_id: int) -> Result:
        self.done.append(f"request {message_id}")
        return Result.ACCEPTED

    def set_message_interval(self, message_id: int, interval_us: float) -> Result:
        self.done.append(f"interval {message_id} {interval_us:g}")
        return Result.ACCEPTED

    def get_message_interval(self, message_id: int) -> Result:
        self.done.append(f"interval of {message_id}")
        return Result.ACCEPTED


@pytest.mark.parametrize(
    ("command", "params", "result", "done"),
    [
        (400, [1], Result.ACCEPTED, ["arm"]),
        (400, [0], Result.ACCEPTED, ["disarm"]),
        (400, [2], Result.DENIED, []),
        (176, [1, 2], Result.ACCEPTED, ["ALT_HOLD"]),
        (176, [1, 0], Result.DENIED, []),  # STABILIZE: a mode the bridge has not
        (176, [0, 19], Result.DENIED, []),  # not a custom mode
        (176, [math.nan, 19], Result.DENIED, []),
        (211, [1, 1], Result.ACCEPTED, ["close"]),
        (211, [1, 0], Result.ACCEPTED, ["open"]),
        (211, [1, 5], Result.DENIED, []),
        (512, [math.inf], Result.DENIED, []),
        (512, [148], Result.ACCEPTED, ["request 148"]),
        (520, [1], Result.ACCEPTED, ["request 148"]),
        (511, [30, 50000], Result.ACCEPTED, ["interval 30 50000"]),
        (511, [30, math.nan], Result.DENIED, []),
        (510, [30], Result.ACCEPTED, ["interval of 30"]),
        (510, [math.nan], Result.DENIED, []),
        (22, [], Result.UNSUPPORTED, []),  # NAV_TAKEOFF
    ],
)
async def test_each_command_gets_a_result_and_odd_values_are_denied(
    command: int, params: list[float], result: Result, done: list[str]
):
    actions = _Actions()
    padded = [*params, *[0.0] * (7 - len(params))]
    assert await handle_command(actions, command, padded) is result
    assert actions.done == done


# -- addressing --------------------------------------------------------------------------------


def test_mavlink_addressing_broadcasts_systems_and_components():
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    def for_us(message: object) -> bool:
        return is_addressed_to(message, system_id=1, component_id=1)

    assert for_us(dialect.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))  # no target: everyone's
    assert not for_us(dialect.MAVLink_manual_control_message(0, 0, 0, 500, 0, 0))  # ArduSub's
    assert for_us(dialect.MAVLink_manual_control_message(1, 0, 0, 500, 0, 0))
    assert not for_us(dialect.MAVLink_manual_control_message(2, 0, 0, 500, 0, 0))
    for system, component, expected in [(1, 1, True), (1, 0, True), (0, 0, True),
                                        (2, 1, False), (1, 100, False)]:  # fmt: skip
        command = dialect.MAVLink_command_long_message(
            system, component, 400, 0, 0, 0, 0, 0, 0, 0, 0
        )
        assert for_us(command) is expected, (system, component)


# -- telemetry messages ------------------------------------------------------------------------


def test_the_heading_is_unknown_until_the_first_reading_not_north():
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    sent: list[tuple[object, ...]] = []
    mav = SimpleNamespace(global_position_int_send=lambda *fields: sent.append(fields))
    endpoint = SimpleNamespace(mav=mav, dialect=dialect)
    state = VehicleState()
    messages = TelemetryMessages(endpoint, state, None, ParameterTable(), lambda: 0.0)  # type: ignore[arg-type]
    messages.send("GLOBAL_POSITION_INT")
    state.update(Sensors(150, 95, False, 0, 0, 0), now_s=1.0)  # heading 0: north, now known
    messages.send("GLOBAL_POSITION_INT")
    assert [fields[-1] for fields in sent] == [65535, 0]  # hdg: UINT16_MAX is "unknown"


def test_a_depth_glitch_does_not_overflow_the_vertical_speed():
    # Before, GLOBAL_POSITION_INT.vz (an int16, cm/s) took the climb rate as it came: a depth
    # reading that jumped (a loose sensor reads full scale) between two fast polls made it
    # overflow, and pymavlink's struct.error ended the bridge.
    from pymavlink.dialects.v20 import ardupilotmega as dialect

    frames: list[bytes] = []
    mav = dialect.MAVLink(SimpleNamespace(write=frames.append), srcSystem=1, srcComponent=1)
    state = VehicleState()
    messages = TelemetryMessages(
        SimpleNamespace(mav=mav, dialect=dialect),  # type: ignore[arg-type]
        state,
        None,  # type: ignore[arg-type]
        ParameterTable(),
        lambda: 0.0,
    )
    vz = []
    state.update(Sensors(0, 20, False, 0, 0, 0), now_s=0.0)
    for climb_cm_s in (-99990.0, 99990.0):  # 9999 cm in 100 ms, down and back up
        state.climb_cm_s = climb_cm_s
        messages.send("GLOBAL_POSITION_INT")
        vz.append(dialect.MAVLink(None).parse_char(frames[-1]).vz)
    assert vz == [32767, -32768]  # + down, as far as the field goes


def test_readings_that_come_close_together_do_not_make_a_climb_rate_of_metres_a_second():
    # A poll that caught up after a missed one came a few milliseconds after the one before:
    # the sensor's 2 cm of noise over 3 ms read as a dive of 6 m/s on the ground station.
    state = VehicleState()
    state.update(Sensors(100, 20, False, 0, 0, 0), now_s=10.0)
    state.update(Sensors(102, 20, False, 0, 0, 0), now_s=10.003)
    assert state.climb_cm_s == 0.0
    state.update(Sensors(101, 20, False, 0, 0, 0), now_s=10.2)  # 1 cm in 0.2 s: a sample
    assert state.climb_cm_s == pytest.approx(0.3 * -1 / 0.2)
