"""The stale-sensor failsafe counts time, not reads: a dead pressure sensor stops the motors
``[board] stale_after_s`` after its first failed read, whatever the control loop's rate, on a
simulated clock. Before, the limit was a number of failed reads in a row, so a dead sensor drove
on five times longer at 20 Hz than at 100 Hz (and five times shorter at 500 Hz)."""

from __future__ import annotations

import pytest

from rovlink.board.board import Board
from rovlink.board.pi.config import STALE_AFTER_S
from rovlink.board.sensors import PolledPressure, PolledSensor
from rovlink.board.server import BoardServer
from rovlink.controller import ConfigError, ControllerConfig, Hardware
from tests.board.rig import example_config
from tests.controller.controller_rig import FakeClaw, FakeClock, FakeImu, FakeLeak, FakeThrusters

_RAW = 512


class _Source:
    """A sensor's driver that gives a reading every ``every`` polls, or fails while dead."""

    def __init__(self, every: int = 1) -> None:
        self.every = every
        self.dead = False
        self.polls = 0

    def poll(self, now_s: float) -> int | None:
        self.polls += 1
        if self.polls % self.every:
            return None  # (a conversion under way: no I/O this period)
        if self.dead:
            raise OSError("no answer")
        return _RAW


class _Loop:
    """The board loop on a fake board with a simulated clock, one pressure sensor."""

    def __init__(self, tick_hz: float, stale_after_s: float = STALE_AFTER_S) -> None:
        self.clock = FakeClock()
        self.source = _Source()
        self.sensor = PolledSensor("pressure sensor", self.source, _RAW, stale_after_s)
        hardware = Hardware(
            FakeThrusters(),
            PolledPressure(self.sensor),
            FakeImu(),
            FakeLeak(),
            FakeClaw(self.clock),
            self.clock,
        )
        board = Board("fake", hardware, make_safe=lambda: None, close=lambda: None)
        board.sensors = [self.sensor]
        self.server = BoardServer(ControllerConfig(tick_hz=tick_hz), board)
        self.period_s = 1.0 / tick_hz

    def run_period(self) -> None:
        self.clock.time_s += self.period_s
        self.server._control_period(self.clock.time_s)

    def driving_for_s_after_the_sensor_dies(self) -> float:
        """How long the robot drives on after its pressure sensor's first failed read."""
        self.server.controller.receive(b"#start!#th.90.50!")
        self.run_period()
        assert not self.server.controller.locked
        self.source.dead = True
        self.run_period()
        died_s = self.clock.time_s
        while not self.server.controller.locked:
            assert self.clock.time_s - died_s < 1.0, "the motors were never stopped"
            self.run_period()
        return self.clock.time_s - died_s


@pytest.mark.parametrize("tick_hz", [20.0, 100.0, 500.0])
def test_a_dead_pressure_sensor_drives_on_for_the_same_time_at_any_loop_rate(
    tick_hz: float,
) -> None:
    loop = _Loop(tick_hz, stale_after_s=0.2)
    # (Stopped at the first period at or after the limit.)
    assert loop.driving_for_s_after_the_sensor_dies() == pytest.approx(0.2, abs=1 / tick_hz)


def test_the_default_is_five_failed_reads_at_the_default_loop_rate() -> None:
    loop = _Loop(ControllerConfig().tick_hz)
    assert loop.driving_for_s_after_the_sensor_dies() == pytest.approx(STALE_AFTER_S)
    assert loop.sensor.failures == 5
    assert loop.sensor.failing_text == "5 failed reads in 0.04 s"


def _failing_sensor(every: int, stale_after_s: float) -> tuple[PolledSensor[int], _Source]:
    source = _Source(every)
    return PolledSensor("IMU", source, _RAW, stale_after_s), source


def test_one_failed_read_of_a_sensor_read_less_often_than_the_limit_is_not_stale() -> None:
    sensor, source = _failing_sensor(every=5, stale_after_s=0.04)  # a reading every 50 ms
    now_s = 0.0
    for _ in range(5):  # a good reading
        now_s += 0.01
        sensor.poll(now_s)
    source.dead = True
    for _ in range(5):  # one failed read, 50 ms after that reading
        now_s += 0.01
        sensor.poll(now_s)
    assert sensor.failures == 1
    assert not sensor.stale
    for _ in range(5):  # a second one, 50 ms after the first: failing for longer than 0.04 s
        now_s += 0.01
        sensor.poll(now_s)
    assert sensor.stale
    source.dead = False
    for _ in range(5):  # stale between failed reads too, until a good reading
        assert sensor.stale
        now_s += 0.01
        sensor.poll(now_s)
    assert not sensor.stale
    assert sensor.failures == 0


def test_a_limit_of_zero_is_stale_at_the_first_failed_read() -> None:
    sensor, source = _failing_sensor(every=1, stale_after_s=0)
    source.dead = True
    assert isinstance(sensor.poll(1.0), OSError)
    assert sensor.stale
    assert sensor.failing_text == "1 failed read in 0.00 s"


@pytest.mark.parametrize("bad", [-0.01, float("nan"), float("inf"), "0.04"])
def test_a_sensor_with_a_bad_limit_is_refused(bad: object) -> None:
    with pytest.raises(ValueError, match="stale_after_s must be"):
        PolledSensor("pressure sensor", _Source(), _RAW, bad)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (-1.0, "rov.toml [board]: stale_after_s must be 0–10 s, got -1.0"),
        (10.5, "rov.toml [board]: stale_after_s must be 0–10 s, got 10.5"),
        (float("nan"), "rov.toml [board]: stale_after_s must be 0–10 s, got nan"),
    ],
)
def test_rov_toml_refuses_a_bad_limit_naming_it(value: float, message: str) -> None:
    with pytest.raises(ConfigError) as caught:
        example_config(board={"stale_after_s": value})
    assert str(caught.value) == message


def test_rov_toml_takes_the_limit_in_seconds() -> None:
    assert example_config().board.stale_after_s == STALE_AFTER_S
    assert example_config(board={"stale_after_s": 0.5}).board.stale_after_s == 0.5
    with pytest.raises(ConfigError, match="unknown key 'stale_after_failures'"):
        example_config(board={"stale_after_failures": 5})
