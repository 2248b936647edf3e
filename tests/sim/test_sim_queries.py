"""A host's queries read the simulated sensors without changing the run they read."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from rovlink.controller import ControllerConfig
from rovlink.sim import SimConfig, SimulatedRobot

_QUERIES = (b"#qd!", b"#qr!", b"#qsa!", b"#qro!", b"#qpi!", b"#qhe!", b"#q.l!")
_TICKS = 400  # 4 s of a dive to 1 m: the depth crosses some 25 of the sensor's counts

#: No link-loss failsafe: the run without queries must not stop for want of frames.
_CONFIG = SimConfig(controller=ControllerConfig(watchdog_s=0.0))


def _dive(queries: dict[int, bytes]) -> tuple[list[tuple[int, ...]], float, float]:
    """The thruster duties of every tick, and the depth and heading at the end, of a dive to
    1 m with ``queries`` (tick → frames) sent along the way."""
    robot = SimulatedRobot(_CONFIG, seed=11)
    robot.receive(b"#start!" + queries.get(0, b"") + b"#mvd.100!")
    duties = []
    for tick in range(1, _TICKS):
        robot.step()
        duties.append(robot.vehicle.duties)
        if tick in queries:
            robot.receive(queries[tick])
    robot.controller.read_output()
    return duties, robot.vehicle.depth_m, robot.vehicle.heading_deg


_UNQUERIED = _dive({})


@settings(max_examples=15, deadline=None)
@given(
    st.dictionaries(
        st.integers(0, _TICKS - 1),
        st.lists(st.sampled_from(_QUERIES), min_size=1, max_size=3).map(b"".join),
        max_size=40,
    )
)
def test_queries_change_neither_what_the_loop_reads_nor_the_motion(
    queries: dict[int, bytes],
) -> None:
    # The pressure queries and the attitude ones drew their noise from the stream the control
    # loop's depth readings came from: every query moved the loop's noise along, and so the
    # depth hold's thrust and the dive itself depended on how often a host asked.
    assert _dive(queries) == _UNQUERIED


def test_each_query_still_converts_afresh() -> None:
    robot = SimulatedRobot(_CONFIG, seed=3)
    robot.set_net_buoyancy(0.0)
    robot.vehicle.depth_m = 2.555  # 147.75 counts above the zero: noise decides the count
    robot.advance(0.5)
    robot.controller.read_output()
    robot.receive(b"#qr!" * 200)
    readings = robot.controller.read_output().split(b"!")[:-1]
    assert set(readings) == {b"$qr.147", b"$qr.148"}
