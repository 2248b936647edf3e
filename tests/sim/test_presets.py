"""Vehicle presets and the seeded heave waves."""

from __future__ import annotations

import math
import statistics

import pytest

from rovlink.sim import SimulatedRobot
from rovlink.sim.presets import PRESETS, preset_config
from rovlink.sim.url import parse_sim_url


def test_presets_differ_in_mass_buoyancy_and_drag() -> None:
    for field in ("mass_kg", "net_buoyancy_n", "heave_drag_n_s2_m2"):
        assert len({getattr(vehicle, field) for vehicle in PRESETS.values()}) == 3
    assert all(vehicle.wave_heave_n > 0 for vehicle in PRESETS.values())


def test_preset_url_option_and_errors() -> None:
    assert parse_sim_url("sim://?preset=heavy").preset == "heavy"
    with pytest.raises(ValueError, match="unknown preset 'huge'; known: heavy, light, standard"):
        parse_sim_url("sim://?preset=huge")
    with pytest.raises(ValueError, match="unknown vehicle preset"):
        preset_config("huge")


def _depths_cm(seed: int, preset: str, seconds: float = 30.0) -> list[float]:
    """A neutrally buoyant hull left at 1 m: only the waves move it."""
    robot = SimulatedRobot(preset_config(preset), seed=seed)
    robot.set_net_buoyancy(0.0)
    robot.vehicle.depth_m = 1.0
    depths = []
    for _ in range(int(seconds / robot.tick_s)):
        robot.step()
        depths.append(robot.vehicle.depth_m * 100.0)
    return depths


def test_heave_waves_move_the_hull_and_are_seeded() -> None:
    first = _depths_cm(1, "heavy")
    assert first == _depths_cm(1, "heavy")
    assert first != _depths_cm(2, "heavy")
    assert max(first) - min(first) > 0.5


def test_heave_waves_fade_with_depth() -> None:
    robot = SimulatedRobot(preset_config("standard"), seed=3)
    vehicle = robot.vehicle
    near, deep = [], []
    for step in range(2000):
        vehicle.time_s = step * 0.01
        vehicle.depth_m = 0.0
        near.append(abs(vehicle.heave_wave_n()))
        vehicle.depth_m = 4.0
        deep.append(abs(vehicle.heave_wave_n()))
    ratio = statistics.mean(deep) / statistics.mean(near)
    assert ratio == pytest.approx(math.exp(-4.0 / 2.0), rel=1e-6)  # decay depth 2 m


def test_no_heave_waves_leave_the_default_vehicle_as_it_was() -> None:
    robot = SimulatedRobot(seed=4)
    assert robot.vehicle.heave_wave_n() == 0.0
