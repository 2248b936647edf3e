"""The simulated vehicle and its sensors, through the controller where it matters."""

from __future__ import annotations

import itertools
import math
import random
import statistics
from collections.abc import Callable
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.controller import ConfigError
from rovlink.controller.config import DEFAULT_THRUSTERS
from rovlink.sim import SimulatedRobot, Vehicle, VehicleParams
from rovlink.sim.robot import sim_config_from_mapping, sim_config_reference
from rovlink.sim.vehicle import thrust_n


def _keep_alive(robot: SimulatedRobot, seconds: float) -> None:
    """Advance, querying every half second as a host would (the watchdog is on)."""
    for _ in range(round(seconds / 0.5)):
        robot.advance(0.5)
        robot.receive(b"#qd!")
    robot.controller.read_output()


def _query(robot: SimulatedRobot, frame: bytes) -> int:
    robot.controller.read_output()
    robot.receive(frame)
    reply = robot.controller.read_output()
    return int(reply.rstrip(b"!").rsplit(b".", 1)[1])


def test_the_idle_robot_floats_at_the_surface() -> None:
    robot = SimulatedRobot(seed=1)
    robot.advance(60.0)
    assert robot.vehicle.depth_m == 0.0
    assert _query(robot, b"#qd!") == 0


def test_released_at_depth_it_rises_at_0_1_to_0_3_m_per_s() -> None:
    robot = SimulatedRobot(seed=1)
    robot.vehicle.depth_m = 8.0
    robot.advance(5.0)  # reach terminal speed
    assert -0.3 <= robot.vehicle.heave_m_s <= -0.1
    start = robot.vehicle.depth_m
    robot.advance(10.0)
    assert 1.0 <= start - robot.vehicle.depth_m <= 3.0


def test_full_vertical_thrust_descends_at_least_0_3_m_per_s() -> None:
    robot = SimulatedRobot(seed=1)
    robot.receive(b"#start!#mvdirect.1!#mvs.-100!")
    _keep_alive(robot, 5.0)
    assert robot.vehicle.heave_m_s >= 0.3
    start = robot.vehicle.depth_m
    _keep_alive(robot, 5.0)
    assert robot.vehicle.depth_m - start >= 1.5


def test_full_up_thrust_at_the_surface_stays_at_the_surface() -> None:
    robot = SimulatedRobot(seed=1)
    robot.receive(b"#start!#mvdirect.1!#mvs.+100!")
    _keep_alive(robot, 5.0)
    assert robot.vehicle.depth_m == 0.0
    assert robot.vehicle.heave_m_s == 0.0


@pytest.mark.parametrize("depth_m", [0.0, 0.37, 1.0, 2.555, 7.31, 12.0, 19.9])
def test_qd_reads_true_depth_to_within_2_cm_with_default_calibration(depth_m: float) -> None:
    robot = SimulatedRobot(seed=3)
    robot.set_net_buoyancy(0.0)  # hold still
    robot.vehicle.depth_m = depth_m
    readings = [_query(robot, b"#qd!") for _ in range(300)]
    assert all(abs(reading - depth_m * 100) <= 2.0 for reading in readings)


def test_the_pressure_reading_is_noisy_between_counts() -> None:
    robot = SimulatedRobot(seed=3)
    robot.set_net_buoyancy(0.0)
    robot.vehicle.depth_m = 2.555  # 147.75 counts above the zero
    readings = [_query(robot, b"#qr!") for _ in range(300)]
    assert set(readings) == {20 + 127, 20 + 128}


def test_the_pressure_sensor_is_10_bit_and_spans_about_20_m() -> None:
    robot = SimulatedRobot(seed=1)
    robot.set_net_buoyancy(0.0)
    robot.vehicle.depth_m = 19.5
    assert _query(robot, b"#qr!") < 1023
    robot.vehicle.depth_m = 30.0
    assert _query(robot, b"#qr!") == 1023  # the converter saturates


def test_a_depth_target_past_the_sensors_span_stops_where_the_reading_saturates() -> None:
    # The converter saturates at 1023 (2006 cm); before, the depth hold pushed on for a target
    # beyond that for ever: 200 m down after four minutes.
    robot = SimulatedRobot(seed=2)
    robot.receive(b"#start!#mvd.2500!")
    depths = []
    for _ in range(60):
        _keep_alive(robot, 2.0)
        depths.append(robot.vehicle.depth_m)
    assert min(depths[20:]) >= 19.0
    assert max(depths) <= 21.0


def test_heading_is_0_to_359_and_follows_the_vehicle() -> None:
    robot = SimulatedRobot(seed=1)
    for true_deg in (0.0, 0.2, 90.0, 359.9, 180.0):
        robot.vehicle.heading_rad = math.radians(true_deg)
        readings = [_query(robot, b"#qhe!") for _ in range(50)]
        assert all(0 <= reading <= 359 for reading in readings)
        errors = [math.remainder(reading - true_deg, 360) for reading in readings]
        assert all(abs(error) <= 3 for error in errors)


def test_roll_and_pitch_are_small_waves_that_fade_with_depth() -> None:
    robot = SimulatedRobot(seed=1)
    rolls = []
    for _ in range(100):  # 10 s at the surface: two wave periods
        robot.advance(0.1)
        rolls.append(robot.imu.read_attitude().roll_deg)
    assert 1.0 < max(rolls) - min(rolls) < 6.0
    robot.set_net_buoyancy(0.0)
    robot.vehicle.depth_m = 10.0
    deep = []
    for _ in range(100):
        robot.advance(0.1)
        deep.append(robot.imu.read_attitude().roll_deg)
    assert max(deep) - min(deep) < 2.5  # what is left is sensor noise
    assert 0.1 < statistics.stdev(deep) < 0.6


def test_full_ahead_moves_along_the_heading_without_turning_much() -> None:
    robot = SimulatedRobot(seed=4)
    heading = robot.vehicle.heading_rad
    robot.receive(b"#start!#th.0.100!")
    _keep_alive(robot, 10.0)
    vehicle = robot.vehicle
    assert 0.8 <= vehicle.surge_m_s <= 2.0
    assert abs(vehicle.sway_m_s) < 0.05
    travelled = math.atan2(vehicle.east_m, vehicle.north_m)
    assert abs(math.remainder(travelled - heading, 2 * math.pi)) < math.radians(20)


def test_sideways_moves_to_starboard() -> None:
    robot = SimulatedRobot(seed=4)
    robot.receive(b"#start!#th.90.100!")
    _keep_alive(robot, 5.0)
    # Propellers push harder forward than in reverse, so the vectored frame drifts a little
    # ahead when it goes sideways, as real ones do.
    assert robot.vehicle.sway_m_s > 0.5
    assert abs(robot.vehicle.surge_m_s) < 0.6 * robot.vehicle.sway_m_s


def test_a_vehicle_turning_under_way_skids_out_of_the_turn() -> None:
    # Regression: the planar equations had no Coriolis or centripetal terms: a vehicle turning
    # under way kept its velocity along its bow, as on rails, its sway exactly 0.
    params = VehicleParams(yaw_disturbance_n_m=0.0)
    vehicle = Vehicle(params, DEFAULT_THRUSTERS, random.Random(1))
    # Full ahead on the left thrusters, less on the right: ahead and turning to starboard, and
    # no sway thrust (the vectored thrusters' sideways pushes cancel out).
    vehicle.set_duties([255, 230, 255, 230, 0, 0])
    for _ in range(2000):
        vehicle.step(0.01)
    surge, sway, rate = vehicle.surge_m_s, vehicle.sway_m_s, vehicle.yaw_rate_rad_s
    assert surge > 0.5
    assert rate > 0.3
    assert sway < -0.1  # to port: out of the starboard turn
    # A steady turn: the sway drag holds the centripetal force m·u·r (to within what steps of
    # 10 ms make of a turn of 70°/s).
    drag_n = params.sway_drag_n_s2_m2 * sway * abs(sway) + params.planar_linear_drag_n_s_m * sway
    assert drag_n == pytest.approx(-params.mass_kg * surge * rate, rel=0.04)


def test_a_hull_without_drag_or_added_mass_goes_on_straight_while_it_spins() -> None:
    params = VehicleParams(
        added_mass_surge_kg=0.0,
        added_mass_sway_kg=0.0,
        surge_drag_n_s2_m2=0.0,
        sway_drag_n_s2_m2=0.0,
        planar_linear_drag_n_s_m=0.0,
        yaw_drag_n_m_s2=0.0,
        yaw_linear_drag_n_m_s=0.0,
        yaw_disturbance_n_m=0.0,
    )
    vehicle = Vehicle(params, DEFAULT_THRUSTERS, random.Random(1))
    heading = vehicle.heading_rad
    vehicle.surge_m_s = 1.0
    vehicle.yaw_rate_rad_s = 1.0  # (a turn every 6.3 s, kept: nothing damps it)
    for _ in range(1000):
        vehicle.step(0.01)
    # Ten seconds, one and a half turns: 10 m along the first heading, at 1 m/s all along.
    assert math.hypot(vehicle.surge_m_s, vehicle.sway_m_s) == pytest.approx(1.0, abs=1e-9)
    assert vehicle.north_m == pytest.approx(10.0 * math.cos(heading), abs=0.05)
    assert vehicle.east_m == pytest.approx(10.0 * math.sin(heading), abs=0.05)


def test_the_heading_wanders_slowly_on_its_own() -> None:
    robot = SimulatedRobot(seed=5)
    headings = []
    for _ in range(120):
        robot.advance(1.0)
        headings.append(robot.vehicle.heading_rad)
    steps = [abs(math.remainder(b - a, 2 * math.pi)) for a, b in itertools.pairwise(headings)]
    assert max(steps) < math.radians(10)  # slow: under 10°/s
    assert sum(steps) > math.radians(1)  # but it does move


def test_a_current_carries_the_idle_vehicle() -> None:
    robot = SimulatedRobot(seed=1)
    robot.set_current(0.3, 90.0)  # toward the east
    robot.advance(60.0)
    vehicle = robot.vehicle
    assert vehicle.east_m > 10.0
    assert abs(vehicle.north_m) < 0.2 * vehicle.east_m


def test_changing_buoyancy_makes_it_sink() -> None:
    robot = SimulatedRobot(seed=1)
    robot.set_net_buoyancy(-2.0)
    robot.advance(20.0)
    assert robot.vehicle.depth_m > 2.0


def test_the_vehicle_rests_on_the_bottom_and_leaves_it_under_up_thrust() -> None:
    # Before, there was no bottom: full down thrust went on for ever, 12 km down in four hours.
    config = sim_config_from_mapping(
        {"controller": {"watchdog_s": 0.0}, "vehicle": {"bottom_depth_m": 3.0}}
    )
    robot = SimulatedRobot(config, seed=1)
    robot.receive(b"#start!#mvdirect.1!#mvs.-100!")
    robot.advance(20.0)
    assert robot.vehicle.depth_m == 3.0
    assert robot.vehicle.heave_m_s == 0.0
    assert abs(_query(robot, b"#qd!") - 300) <= 2
    robot.receive(b"#mvs.+100!")
    robot.advance(1.0)
    assert robot.vehicle.depth_m < 2.8


def _terminal_speed_m_s(force_n: float, quadratic: float, linear: float) -> float:
    """The speed at which drag (quadratic·v² + linear·v) balances ``force_n``."""
    return (-linear + math.sqrt(linear * linear + 4.0 * quadratic * force_n)) / (2.0 * quadratic)


@settings(max_examples=40, deadline=None)
@given(
    net_buoyancy_n=st.floats(-30.0, 30.0),
    bottom_depth_m=st.floats(0.5, 60.0),
    start_fraction=st.floats(0.0, 1.0),
    commands=st.lists(
        st.tuples(
            st.lists(st.integers(-255, 255), min_size=6, max_size=6),
            st.floats(0.001, 2.0),
        ),
        min_size=1,
        max_size=25,
    ),
)
def test_any_thrust_and_step_keeps_the_vehicle_in_the_water_and_its_speeds_bounded(
    net_buoyancy_n: float,
    bottom_depth_m: float,
    start_fraction: float,
    commands: list[tuple[list[int], float]],
) -> None:
    params = VehicleParams(net_buoyancy_n=net_buoyancy_n, bottom_depth_m=bottom_depth_m)
    vehicle = Vehicle(params, DEFAULT_THRUSTERS, random.Random(1))
    vehicle.depth_m = start_fraction * bottom_depth_m
    g = 9.80665
    # From rest, drag taken at the end of each step never lets a speed pass the terminal speed
    # of the strongest force the vehicle can feel: no energy comes from the integration.
    heave_limit = _terminal_speed_m_s(
        abs(net_buoyancy_n) + 2 * params.forward_thrust_kgf * g,
        params.heave_drag_n_s2_m2,
        params.heave_linear_drag_n_s_m,
    )
    surge_limit, sway_limit = (
        _terminal_speed_m_s(
            4 * params.forward_thrust_kgf * g, drag, params.planar_linear_drag_n_s_m
        )
        for drag in (params.surge_drag_n_s2_m2, params.sway_drag_n_s2_m2)
    )
    for duties, dt_s in commands:
        vehicle.set_duties(duties)
        vehicle.step(dt_s)
        assert 0.0 <= vehicle.depth_m <= bottom_depth_m
        assert abs(vehicle.heave_m_s) <= heave_limit * (1 + 1e-9)
        assert abs(vehicle.surge_m_s) <= surge_limit * (1 + 1e-9)
        assert abs(vehicle.sway_m_s) <= sway_limit * (1 + 1e-9)
        assert 0.0 <= vehicle.heading_deg < 360.0


@pytest.mark.parametrize(
    ("hook", "why"),
    [
        # Before, NaN or infinity went into the physics and ended the run at the next pressure
        # reading with a traceback; a NaN event time stopped every later event.
        (lambda robot: robot.set_net_buoyancy(math.nan), "net_buoyancy_n must be a finite"),
        (lambda robot: robot.set_net_buoyancy(-math.inf), "net_buoyancy_n must be a finite"),
        (lambda robot: robot.set_current(math.inf, 90.0), "speed_m_s must be a finite"),
        (lambda robot: robot.set_current(0.5, math.nan), "toward_deg must be a finite"),
        (lambda robot: robot.inject_leak(at_s=math.nan), "at_s must be a finite"),
        (lambda robot: robot.inject_leak(duration_s=-1.0), "duration_s must be ≥ 0"),
        (lambda robot: robot.inject_leak(duration_s=math.nan), "duration_s must be ≥ 0"),
        (lambda robot: robot.schedule(math.nan, lambda: None), "at_s must be a finite"),
    ],
)
def test_scenario_hooks_refuse_what_is_not_a_number_and_change_nothing(
    hook: Callable[[SimulatedRobot], None], why: str
) -> None:
    robot = SimulatedRobot(seed=1)
    fired: list[float] = []
    robot.schedule(1.0, lambda: fired.append(robot.time_s))
    with pytest.raises(ValueError, match=f"^{why}"):
        hook(robot)
    robot.advance(2.0)  # runs on, its scheduled event included
    robot.receive(b"#qd!#q.l!")
    assert robot.controller.read_output() == b"$qd.0!$q.l.0!"
    assert fired == [1.0]
    assert (robot.vehicle.current_north_m_s, robot.vehicle.current_east_m_s) == (0.0, 0.0)


def test_a_leak_for_good_stays() -> None:
    robot = SimulatedRobot(seed=1)
    robot.inject_leak(at_s=0.5, duration_s=math.inf)
    robot.advance(1.0)
    robot.receive(b"#slreset!")
    robot.advance(1.0)
    robot.receive(b"#q.l!")
    assert robot.controller.read_output() == b"$q.l.1!"


def test_a_leak_pulse_between_ticks_is_latched() -> None:
    robot = SimulatedRobot(seed=1)
    robot.advance(1.0)
    robot.inject_leak(at_s=1.0031, duration_s=0.001)
    robot.advance(0.02)
    assert _query(robot, b"#q.l!") == 1


def test_scheduled_actions_run_at_their_simulated_time() -> None:
    robot = SimulatedRobot(seed=1)
    robot.vehicle.depth_m = 5.0
    robot.schedule(2.0, lambda: robot.set_net_buoyancy(0.0))
    robot.advance(1.0)
    assert robot.vehicle.net_buoyancy_n > 0
    robot.advance(1.01)
    assert robot.vehicle.net_buoyancy_n == 0.0


def test_claw_pulses_move_the_claw() -> None:
    robot = SimulatedRobot(seed=1)
    robot.receive(b"#start!#h+!")
    robot.advance(0.5)
    assert robot.claw.opening == pytest.approx(0.05 / 2.0, abs=0.006)
    robot.receive(b"#h-!")
    robot.advance(0.5)
    assert robot.claw.opening == pytest.approx(0.0, abs=0.006)


def test_same_seed_same_run_other_seed_other_noise() -> None:
    def run(seed: int) -> tuple[list[float], bytes]:
        robot = SimulatedRobot(seed=seed)
        robot.receive(b"#start!#mvd.150!#th.30.40!")
        trace = []
        for _ in range(40):
            robot.advance(0.25)
            robot.receive(b"#qsa!")
            trace.append(robot.vehicle.depth_m)
        return trace, robot.controller.read_output()

    assert run(7) == run(7)
    assert run(7)[1] != run(8)[1]


def test_the_thruster_curve() -> None:
    params = VehicleParams()
    assert thrust_n(0, params) == 0.0
    assert thrust_n(5, params) == 0.0  # dead band
    assert thrust_n(255, params) == pytest.approx(2.5 * 9.80665)
    assert thrust_n(-255, params) == pytest.approx(-2.0 * 9.80665)
    forward = [thrust_n(duty, params) for duty in range(0, 256)]
    assert forward == sorted(forward)
    assert thrust_n(128, params) < 0.5 * thrust_n(255, params)  # more than linear


def test_invalid_vehicle_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="mass_kg"):
        VehicleParams(mass_kg=0.0)


@pytest.mark.parametrize(
    ("table", "key", "value", "why"),
    [
        # Before, each of these ran until the first reading and then ended the simulator with a
        # traceback (NaN or infinity in the depth), or divided by zero at start.
        ("vehicle", "net_buoyancy_n", math.nan, "must be a finite number, got nan"),
        ("vehicle", "wave_roll_deg", math.inf, "must be a finite number, got inf"),
        ("vehicle", "roll_trim_deg", math.nan, "must be a finite number"),
        ("vehicle", "yaw_disturbance_n_m", math.inf, "must be a finite number"),
        ("vehicle", "thruster_time_constant_s", -0.1, "must be ≥ 0"),
        ("vehicle", "added_mass_heave_kg", -12.0, "must be ≥ 0"),  # a mass of 0 in heave
        ("vehicle", "heave_drag_n_s2_m2", -50.0, "must be ≥ 0"),
        ("vehicle", "thruster_curve_linear", 5.0, r"must be in \[0, 1\]"),
        ("sensors", "pressure_zero_raw", math.nan, "must be a finite number"),
        ("sensors", "heading_noise_deg", math.inf, "must be a finite number"),
        ("sensors", "pressure_noise_counts", -1.0, "must be ≥ 0"),
        ("sensors", "claw_travel_s", math.inf, "must be a finite number"),
    ],
)
def test_nonsense_in_the_vehicle_or_sensors_table_is_refused_naming_the_key(
    table: str, key: str, value: float, why: str
) -> None:
    with pytest.raises(ConfigError, match=rf"^sim\.toml \[{table}\]: {key} {why}"):
        sim_config_from_mapping({table: {key: value}}, "sim.toml")


@pytest.mark.parametrize("tick_hz", [1.0, 2.0, 10.0])
def test_the_physics_does_not_depend_on_the_controllers_rate(tick_hz: float) -> None:
    # The vehicle steps at most 10 ms at a time: before, at 1 Hz full down thrust bounced
    # between the surface and 1.9 m, and at 2 Hz it sank a third faster than at 100 Hz.
    config = sim_config_from_mapping({"controller": {"tick_hz": tick_hz, "watchdog_s": 0.0}})
    robot = SimulatedRobot(config, seed=1)
    robot.receive(b"#start!#mvdirect.1!#mvs.-100!")
    reference = SimulatedRobot(sim_config_from_mapping({"controller": {"watchdog_s": 0.0}}), seed=1)
    reference.receive(b"#start!#mvdirect.1!#mvs.-100!")
    robot.advance(4.0)
    reference.advance(4.0)
    depths = []
    for _ in range(6):
        robot.advance(1.0)
        reference.advance(1.0)
        depths.append(robot.vehicle.depth_m)
        assert robot.vehicle.heave_m_s == pytest.approx(reference.vehicle.heave_m_s, rel=0.02)
    assert depths == sorted(depths)  # down and down, never back at the surface


def test_a_heavy_drag_gives_a_slow_steady_descent() -> None:
    # Drag is taken at the end of each step: before, a drag this strong made the speed flip
    # sign every step, and the vehicle full down stayed at the surface.
    config = sim_config_from_mapping(
        {"controller": {"watchdog_s": 0.0}, "vehicle": {"heave_drag_n_s2_m2": 1e6}}
    )
    robot = SimulatedRobot(config, seed=1)
    robot.receive(b"#start!#mvdirect.1!#mvs.-100!")
    robot.advance(5.0)
    speeds = []
    for _ in range(100):
        robot.advance(0.05)
        speeds.append(robot.vehicle.heave_m_s)
    # The terminal speed: the net downward force (full reverse thrust less the buoyancy) over
    # the drag, as √(F / drag).
    terminal = math.sqrt((2 * 2.0 * 9.80665 - 2.0) / 1e6)
    assert all(speed == pytest.approx(terminal, rel=0.05) for speed in speeds)


def test_duties_beyond_full_are_full_thrust() -> None:
    robot = SimulatedRobot(seed=1)
    robot.vehicle.set_duties([0, 0, 0, 0, -400, -400])  # an ESC saturates; no KeyError
    assert robot.vehicle.duties == (0, 0, 0, 0, -255, -255)


def test_docs_contain_the_simulator_reference() -> None:
    docs = Path(__file__).resolve().parents[2] / "docs" / "controller.md"
    assert sim_config_reference() in docs.read_text(encoding="utf-8")
