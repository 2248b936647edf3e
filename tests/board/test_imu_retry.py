"""An IMU that did not start, started again in the background, on a simulated clock."""

from __future__ import annotations

import pytest

from rovlink.board.pi.bno055 import Bno055Imu
from rovlink.board.pi.fake_bus import FakeBno055, FakeI2cBus
from rovlink.board.pi.imu_retry import ImuStartedInBackground
from rovlink.board.sensors import SensorError
from rovlink.controller import Attitude
from tests.board.rig import wait_until


def _poll(retry: ImuStartedInBackground, now_s: float) -> object:
    """One control period's poll, then the end of the try it began (the test's own pace)."""
    try:
        result: object = retry.poll(now_s)
    except SensorError as error:
        result = error
    assert wait_until(lambda: not retry.trying)
    return result


def test_tries_are_bounded_and_the_attitude_is_read_once_it_answers() -> None:
    bus = FakeI2cBus({})  # the chip still booting: nothing answers at its address
    started: list[bool] = []
    retry = ImuStartedInBackground(
        Bno055Imu(bus),
        "IMU BNO055 at 0x28 on I²C bus 1",
        "did not start",
        retry_interval_s=1.0,
        on_started=lambda: started.append(True),
    )
    try:
        # Five seconds of 10 ms control periods: a try a second at most, every poll an error.
        results = [_poll(retry, period * 0.01) for period in range(500)]
        assert all(isinstance(result, SensorError) for result in results)
        assert "started again every 1 s" in str(results[-1])
        assert 3 <= retry.tries <= 5
        assert not started
        bus.devices[0x28] = FakeBno055(heading_deg=90.0)
        now_s = 5.0
        while not started and now_s < 10.0:
            result = _poll(retry, now_s)
            now_s += 0.01
        assert started
        assert isinstance(result, Attitude)
        assert result.heading_deg == pytest.approx(90.0)
    finally:
        retry.close()
