"""The bridges' sensor poller: a cancellation ends its wait, whatever else wakes it."""

from __future__ import annotations

import asyncio
from typing import cast

import pytest

from rovlink.bridges.sensor_poll import SensorPoller
from rovlink.client.sensors import Sensors
from rovlink.piloting.tracked import TrackedClient

_READING = Sensors(
    depth_cm=0, pressure_raw=0, leak_detected=False, roll_deg=0, pitch_deg=0, heading_deg=0
)


class _InstantRobot:
    """Answers ``#qsa!`` at once."""

    def __init__(self) -> None:
        self.polls = 0

    async def sensors(self) -> Sensors:
        self.polls += 1
        return _READING


async def test_a_rate_change_that_comes_with_the_cancellation_does_not_keep_it_polling() -> None:
    # On Python 3.10 asyncio.wait_for swallowed a cancellation that came as its event was set
    # (bpo-37658): a bridge whose poll rate a ground station changed as it ended ran on.
    robot = _InstantRobot()
    poller = SensorPoller(cast(TrackedClient, robot), lambda reading: None, rate_hz=1.0)
    task = asyncio.create_task(poller.run())
    while robot.polls == 0:
        await asyncio.sleep(0)
    await asyncio.sleep(0.01)  # waiting for the next poll's time
    poller.set_rate(50.0)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await asyncio.wait_for(task, 2.0)
