"""Simulation speed in fast mode: simulated seconds per wall second (real time is 1×).

Two measurements of the same stepping code (controller tick + physics at 100 Hz):

* ``step loop``: a host script driven in-line — unlock, dive to 3 m, move, query all sensors
  twice a second — on :class:`rovlink.sim.SimulatedRobot`;
* ``fast port``: :class:`rovlink.sim.SimulatedPort` started with ``realtime=False`` (what
  ``open_port(realtime=False)`` returns), its thread running as fast as it can while the caller
  waits, as a ``sim://`` user would see it.

Also the cost of one tick split into controller and physics.

    PYTHONPATH=src python bench/sim_speed.py [--seconds 600] [--repeat 3]
"""

from __future__ import annotations

import argparse
import statistics
import time
import timeit

from rovlink.controller import ControllerConfig
from rovlink.sim import SimConfig, SimulatedPort, SimulatedRobot

TARGET_SPEEDUP = 1000.0
QUERY_EVERY_S = 0.5
_NO_WATCHDOG = SimConfig(controller=ControllerConfig(watchdog_s=0.0))


def step_loop(seconds: float) -> float:
    """Simulated seconds per wall second of an in-line host script."""
    robot = SimulatedRobot(seed=1)
    receive = robot.receive
    ticks_per_query = round(QUERY_EVERY_S / robot.tick_s)
    receive(b"#start!#mvd.300!#th.30.60!")
    step = robot.step
    started = time.perf_counter()
    for tick in range(round(seconds / robot.tick_s)):
        if tick % ticks_per_query == 0:
            receive(b"#qsa!")
            robot.controller.read_output()
        step()
    elapsed = time.perf_counter() - started
    assert not robot.controller.locked
    return seconds / elapsed


def fast_port(seconds: float) -> float:
    """Simulated seconds per wall second of the fast-mode simulation thread."""
    # No host keeps the link alive while the thread runs alone: without the watchdog the robot
    # keeps diving and moving, the costlier case.
    port = SimulatedPort(_NO_WATCHDOG, seed=1, timeout=0)
    port.write(b"#start!#mvd.300!#th.30.60!")
    started = time.perf_counter()
    port.start(realtime=False)
    while port.robot.time_s < seconds:
        time.sleep(0.01)
    elapsed = time.perf_counter() - started
    simulated = port.robot.time_s
    port.close()
    return simulated / elapsed


def tick_costs_us() -> tuple[float, float]:
    """Median microseconds of one controller tick and one physics step while diving."""
    robot = SimulatedRobot(_NO_WATCHDOG, seed=1)
    robot.receive(b"#start!#mvd.300!#th.30.60!")
    robot.advance(1.0)
    count = 20_000
    tick = min(timeit.repeat(robot.controller.tick, number=count, repeat=5)) / count
    physics = (
        min(timeit.repeat(lambda: robot.vehicle.step(robot.tick_s), number=count, repeat=5)) / count
    )
    return tick * 1e6, physics * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seconds", type=float, default=600.0, help="simulated seconds a run")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each; the median counts")
    arguments = parser.parse_args()

    loop = [step_loop(arguments.seconds) for _ in range(arguments.repeat)]
    port = [fast_port(arguments.seconds) for _ in range(arguments.repeat)]
    tick_us, physics_us = tick_costs_us()
    print(f"simulated {arguments.seconds:g} s at 100 Hz, {arguments.repeat} runs each (median):")
    for name, speeds in (("step loop", loop), ("fast port", port)):
        median = statistics.median(speeds)
        print(
            f"  {name:<10} {median:8.0f}× real time  (runs: "
            f"{', '.join(f'{speed:.0f}' for speed in speeds)}); "
            f"ratio to the {TARGET_SPEEDUP:g}× target {median / TARGET_SPEEDUP:.2f}"
        )
    print(f"one tick: controller {tick_us:.2f} µs + physics {physics_us:.2f} µs")


if __name__ == "__main__":
    main()
