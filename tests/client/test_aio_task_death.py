"""Every way a task driving the robot through the asyncio client can die leaves it stopped: on
the simulated controller (``sim://``), its thrust is zero and its motors locked afterwards."""

from __future__ import annotations

import asyncio
import sys
from collections.abc import Awaitable, Callable

import pytest

import rovlink.aio
from rovlink.aio import AsyncClient
from rovlink.controller import ControllerState
from rovlink.sim import SimulatedPort
from tests.client.conftest import CONDITION_TIMEOUT_S, REPLY_TIMEOUT_S

Timeouts = (TimeoutError, asyncio.TimeoutError)  # one class from Python 3.11 on


def _state(rov: AsyncClient) -> ControllerState:
    port = rov._link.port  # type: ignore[attr-defined]
    assert isinstance(port, SimulatedPort)
    with port.lock:
        return port.controller.state()


class _Pilot:
    """A task's program: unlock, move, thrust down, then its control loop (``control``)."""

    def __init__(self, control: Callable[[AsyncClient], Awaitable[None]]) -> None:
        self.control = control
        self.moving = asyncio.Event()
        self.rov: AsyncClient | None = None
        self.state_when_moving: ControllerState | None = None

    async def __call__(self) -> None:
        async with rovlink.aio.connect("sim://?seed=3", timeout=REPLY_TIMEOUT_S) as rov:
            self.rov = rov
            await rov.start()
            await rov.move(90, 40)
            await rov.set_direct_mode(True)
            await rov.set_vertical_thrust(-30)
            self.state_when_moving = _state(rov)
            self.moving.set()
            await self.control(rov)


async def _renewing(rov: AsyncClient) -> None:
    """A control loop that renews the motion and reads the depth, for ever."""
    while True:
        await rov.move(90, 40)
        await rov.depth_cm()


async def _raising(rov: AsyncClient) -> None:
    await rov.depth_cm()
    raise KeyError("bug in the control loop")


async def _timing_out(rov: AsyncClient) -> None:
    await asyncio.wait_for(_renewing(rov), 0.02)


async def _dies_raising() -> _Pilot:
    pilot = _Pilot(_raising)
    with pytest.raises(KeyError):
        await pilot()
    return pilot


async def _dies_timing_out() -> _Pilot:
    pilot = _Pilot(_timing_out)
    with pytest.raises(Timeouts):
        await pilot()
    return pilot


async def _dies_cancelled() -> _Pilot:
    pilot = _Pilot(_renewing)
    task = asyncio.ensure_future(pilot())
    await pilot.moving.wait()
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    return pilot


async def _dies_with_a_failing_sibling() -> _Pilot:
    pilot = _Pilot(_renewing)

    async def user_interface() -> None:
        await pilot.moving.wait()
        raise KeyError("bug in the user interface")

    if sys.version_info >= (3, 11):  # the TaskGroup cancels the pilot

        async def group() -> None:
            async with asyncio.TaskGroup() as tasks:  # type: ignore[attr-defined,unused-ignore]
                tasks.create_task(pilot())
                tasks.create_task(user_interface())

        with pytest.raises(BaseExceptionGroup):  # noqa: F821 - a builtin from 3.11 on
            await group()
    else:  # (3.10: gather, and the pilot cancelled by hand, as a program does)
        tasks = [asyncio.ensure_future(pilot()), asyncio.ensure_future(user_interface())]
        with pytest.raises(KeyError):
            await asyncio.gather(*tasks)
        tasks[0].cancel()
        with pytest.raises(asyncio.CancelledError):
            await tasks[0]
    return pilot


DEATHS: dict[str, Callable[[], Awaitable[_Pilot]]] = {
    "raises": _dies_raising,
    "times out": _dies_timing_out,
    "cancelled": _dies_cancelled,
    "a sibling task fails": _dies_with_a_failing_sibling,
}


@pytest.mark.parametrize("death", DEATHS)
async def test_a_pilot_task_that_dies_leaves_the_robot_stopped(death: str) -> None:
    pilot = await asyncio.wait_for(DEATHS[death](), CONDITION_TIMEOUT_S)
    before = pilot.state_when_moving
    assert before is not None
    assert (before.locked, before.power_percent, before.vertical_thrust_percent) == (False, 40, -30)
    assert pilot.rov is not None
    assert pilot.rov.closed
    after = _state(pilot.rov)
    assert (after.locked, after.power_percent, after.vertical_thrust_percent) == (True, 0, 0)
