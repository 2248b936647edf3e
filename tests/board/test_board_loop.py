"""The board loop with the Pi's drivers on fake buses, served on a real pseudo-terminal.

Every check reads the pulses the PCA9685 makes, rebuilt from the recorded I²C transactions.
"""

from __future__ import annotations

import dataclasses
import os
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from typing import Any

import pytest

from rovlink.board.board import BoardStartError
from rovlink.board.pi.bno055 import Bno055Imu
from rovlink.board.pi.board import fake_bus_for, open_pi_board, set_pi_outputs_at_rest
from rovlink.board.pi.config import PiConfig, pi_config_from_mapping
from rovlink.board.pi.fake_bus import FakeBno055, FakeI2cBus, FakeMs5837, FakePca9685
from rovlink.board.server import BoardServer
from rovlink.board.watchdog_bounds import MAX_BOARD_WATCHDOG_S
from rovlink.controller import LeakAction
from tests.board.rig import (
    CLAW_CHANNEL,
    CONDITION_TIMEOUT_S,
    COUNT_US,
    PCA_ADDRESS,
    SECOND_PCA_ADDRESS,
    THRUSTER_CHANNELS,
    example_config,
    is_neutral,
    pulses,
    two_pwm_boards_data,
    wait_until,
    with_controller,
)

pytestmark = pytest.mark.integration

#: `#th.90.50!` on the example layout: the horizontal thrusters at ±45° to starboard get
#: ±0.5 of full thrust, duty ±128 (P8, P11); channels 1, 3 and 5 are reversed in the example.
TH_90_50_US = [
    1500 + 400 * 128 / 255,  # front_left, 45°: +128
    1500 + 400 * 128 / 255,  # front_right, 315°: −128, reversed
    1500 - 400 * 128 / 255,  # rear_left, 315°: −128
    1500 - 400 * 128 / 255,  # rear_right, 45°: +128, reversed
    1500.0,  # vertical_left: depth mode, no target
    1500.0,  # vertical_right
]


@dataclass
class Running:
    server: BoardServer
    bus: FakeI2cBus
    fd: int
    pins: Any
    errors: list[BaseException] = field(default_factory=list)
    received: bytearray = field(default_factory=bytearray)

    def send(self, data: bytes) -> None:
        os.write(self.fd, data)

    def pulses(self) -> list[float | None]:
        return pulses(self.bus.snapshot())

    def moving_as_commanded(self) -> bool:
        values = self.pulses()
        return all(
            value is not None and abs(value - expected) <= COUNT_US
            for value, expected in zip(values, TH_90_50_US, strict=True)
        )

    def neutral(self) -> bool:
        return is_neutral(self.pulses())

    def saw(self, fragment: bytes) -> bool:
        with suppress(BlockingIOError):
            self.received += os.read(self.fd, 4096)
        return fragment in self.received


@contextmanager
def running(config: PiConfig) -> Iterator[Running]:
    with running_on(config, fake_bus_for(config)) as rig:
        yield rig


@contextmanager
def running_on(config: PiConfig, bus: FakeI2cBus) -> Iterator[Running]:
    from gpiozero.pins.mock import MockFactory

    pins = MockFactory()
    board = open_pi_board(config, bus=bus, pin_factory=pins)
    server = BoardServer(config.controller, board)
    path = server.open_pty()
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    stop = threading.Event()
    rig = Running(server, bus, fd, pins)

    def serve() -> None:
        try:
            server.serve(stop.is_set)
        except BaseException as error:
            rig.errors.append(error)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield rig
    finally:
        stop.set()
        thread.join(10)
        os.close(fd)
        server.close()
        pins.close()


def _quick(**controller: Any) -> PiConfig:
    """The example without the IMU (its driver's reset takes a second) and ``controller``."""
    return with_controller(example_config(imu={"sensor": "none"}), **controller)


def test_neutral_before_anything_then_the_commanded_pulses_then_neutral_on_stop() -> None:
    with running(example_config()) as rig:
        assert rig.neutral()
        assert pulses(rig.bus.snapshot(), [CLAW_CHANNEL]) == pytest.approx([1500.0], abs=COUNT_US)
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        rig.send(b"#qhe!")
        assert wait_until(lambda: rig.saw(b"$qhe.90!"))  # the fake BNO055's heading
        rig.send(b"#stop!")
        assert wait_until(rig.neutral), rig.pulses()
        assert rig.server.controller.locked
    assert not rig.errors


def test_the_link_loss_watchdog_gives_neutral() -> None:
    with running(_quick(watchdog_s=0.3)) as rig:
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        assert wait_until(rig.neutral), rig.pulses()  # nothing more is sent
        assert rig.server.controller.locked


def test_an_exception_in_the_control_loop_ends_it_at_neutral() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)

        def broken_tick() -> None:
            raise RuntimeError("a bug in the control loop")

        rig.server.controller.tick = broken_tick  # type: ignore[method-assign]
        assert wait_until(lambda: bool(rig.errors))
        assert isinstance(rig.errors[0], RuntimeError)
        assert rig.neutral(), rig.pulses()
        assert rig.server.at_rest


def test_one_failed_write_to_the_pwm_board_is_retried() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#start!")
        rig.bus.fail(0x40, 1)
        rig.send(b"#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        assert any(t.failed and t.address == 0x40 for t in rig.bus.snapshot())
        assert not rig.errors


def test_an_i2c_error_on_the_pwm_board_ends_the_loop_at_neutral_after_a_retry() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        # The stop's write and its retry fail, and so does the first attempt at neutral.
        rig.bus.fail(0x40, 3)
        rig.send(b"#stop!")
        assert wait_until(lambda: bool(rig.errors))
        assert isinstance(rig.errors[0], OSError)
        assert rig.neutral(), rig.pulses()
        assert rig.server.at_rest


def test_a_failed_write_to_the_moving_claw_does_not_hold_up_the_stop() -> None:
    # Before, the stop wrote the claw's rest first, without a retry: one I²C error on it ended
    # the stop (and the loop) before the thrusters were set to neutral.
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S, claw_pulse_ms=5000)) as rig:
        rig.send(b"#start!#th.90.50!#h+!")
        claw = lambda: pulses(rig.bus.snapshot(), [CLAW_CHANNEL])[0]  # noqa: E731
        at_rest = lambda: claw() == pytest.approx(1500.0, abs=COUNT_US)  # noqa: E731
        assert wait_until(lambda: rig.moving_as_commanded() and not at_rest())
        rig.bus.fail(0x40, 1)
        rig.send(b"#stop!")
        assert wait_until(lambda: rig.neutral() and at_rest()), rig.pulses()
        assert rig.server.controller.locked
        assert any(t.failed and t.address == 0x40 for t in rig.bus.snapshot())
    assert not rig.errors


def test_a_stale_pressure_sensor_stops_the_motors_until_it_answers() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        rig.bus.fail(0x76, 10**6)
        assert wait_until(rig.neutral), rig.pulses()
        assert rig.server.controller.locked
        assert wait_until(lambda: rig.saw(b"read failed"))
        # (How many reads fail in stale_after_s depends on the loop's timing: not said here.)
        assert wait_until(lambda: rig.saw(b"at 0x76 stale ("))
        assert wait_until(lambda: rig.saw(b" s): motors stopped"))
        # Started again while the sensor is still dead: stopped again.
        rig.send(b"#start!#th.90.50!")
        assert wait_until(lambda: rig.server.controller.locked)
        assert wait_until(rig.neutral)
        rig.bus.fail(0x76, 0)
        assert wait_until(lambda: rig.saw(b"answers again"))
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
    assert not rig.errors


def test_a_dead_imu_is_said_to_be_stale_and_the_robot_can_still_be_driven() -> None:
    # The controller steers by no attitude (no yaw command, P11: no heading hold), so a dead
    # compass must not stop the thrusters mid-dive; the pilot is told what no longer reads.
    with running(with_controller(example_config(), watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        imu = rig.server.board.sensors[1]
        rig.bus.fail(0x28, 10**6)
        assert wait_until(lambda: rig.saw(b"IMU BNO055 at 0x28 stale ("))
        assert wait_until(
            lambda: rig.saw(
                b" s): roll, pitch and heading "
                b"are not measured, qro, qpi and qhe repeat the last good reading; driving goes on"
            )
        ), rig.received
        assert imu.stale
        assert not rig.server.controller.locked
        assert rig.moving_as_commanded(), rig.pulses()
        rig.send(b"#th.0.0!#qsa!")  # still driven by hand, and every sensor still answers
        assert wait_until(lambda: rig.saw(b"$qhe.90!"))
        assert wait_until(rig.neutral), rig.pulses()
        rig.send(b"#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        assert b"failsafe" not in rig.received
        rig.bus.fail(0x28, 0)
        assert wait_until(lambda: rig.saw(b"IMU BNO055 at 0x28 answers again"))
    assert not rig.errors


def test_fewer_failures_than_the_limit_do_not_stop_the_motors() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        rig.bus.fail(0x76, 2)
        assert wait_until(lambda: rig.saw(b"read failed"))
        sensor = rig.server.board.sensors[0]
        assert wait_until(lambda: sensor.total_failures == 2 and sensor.failures == 0)
        assert not rig.server.controller.locked
        assert rig.moving_as_commanded()


def test_a_pressure_sensor_reset_mid_dive_costs_one_read_and_depth_comes_back() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        ms5837 = rig.bus.devices[0x76]
        assert isinstance(ms5837, FakeMs5837)
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        sensor = rig.server.board.sensors[0]
        before = sensor.total_failures
        ms5837.power_on_reset()  # the conversion under way is lost: the ADC read gives 0
        assert wait_until(lambda: rig.saw(b"conversion read as 0"))
        assert wait_until(lambda: sensor.total_failures == before + 1 and sensor.failures == 0)
        assert ms5837.resets == 2  # at start, and the datasheet's reset after a power-on
        assert not rig.server.controller.locked  # one failed read: not stale
        assert rig.moving_as_commanded()
        ms5837.set_reading(1013.25 + 2.5 * 997.0 * 9.80665 / 100)  # 2.5 m (the example's water)

        def reads_the_new_depth() -> bool:  # from the next conversions on
            rig.send(b"#qd!")
            return rig.saw(b"$qd.250!")

        assert wait_until(reads_the_new_depth), rig.received
    assert not rig.errors


def test_a_leak_pulse_stops_the_motors_with_leak_action_stop() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        pin = rig.pins.pin(27)
        pin.drive_high()
        pin.drive_low()
        assert wait_until(rig.neutral), rig.pulses()
        rig.send(b"#q.l!")
        assert wait_until(lambda: rig.saw(b"$q.l.1!"))


#: The vertical thrusters' pulses at full up thrust (vertical_right is reversed).
_FULL_UP_US = [1900.0, 1100.0]


def test_a_pressure_sensor_that_dies_while_surfacing_for_a_leak_lets_it_surface() -> None:
    # Water that set off the leak probe reaches the pressure sensor's wiring: the stale-sensor
    # failsafe stopped the surfacing that leak_action = "surface" started, which needs no
    # depth, and left the leaking robot where it was.
    config = _quick(watchdog_s=MAX_BOARD_WATCHDOG_S, leak_action=LeakAction.SURFACE)
    with running(config) as rig:
        vertical = lambda: pulses(rig.bus.snapshot(), [4, 5])  # noqa: E731
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        rig.pins.pin(27).drive_high()
        assert wait_until(lambda: vertical() == pytest.approx(_FULL_UP_US, abs=COUNT_US))
        rig.bus.fail(0x76, 10**6)
        pressure = rig.server.board.sensors[0]
        assert wait_until(lambda: pressure.stale)
        assert wait_until(lambda: rig.saw(b"surfacing for the leak goes on")), rig.received
        assert not rig.server.controller.locked
        assert vertical() == pytest.approx(_FULL_UP_US, abs=COUNT_US)
        # A host that drives again drives a robot whose depth is not measured: stopped.
        rig.send(b"#mvs.50!")
        assert wait_until(lambda: rig.server.controller.locked)
        assert wait_until(rig.neutral), rig.pulses()
        assert wait_until(lambda: rig.saw(b"failsafe: pressure sensor"))
    assert not rig.errors


def test_the_claw_motor_runs_for_its_pulse_then_stops() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S, claw_pulse_ms=200)) as rig:
        rig.send(b"#start!#h+!")
        claw = lambda: pulses(rig.bus.snapshot(), [CLAW_CHANNEL])[0]  # noqa: E731
        assert wait_until(lambda: claw() == pytest.approx(1900.0, abs=COUNT_US))
        assert wait_until(lambda: claw() == pytest.approx(1500.0, abs=COUNT_US))


def test_a_missing_device_is_refused_at_start_naming_it_with_the_outputs_at_neutral() -> None:
    from gpiozero.pins.mock import MockFactory

    config = example_config()
    bus = fake_bus_for(config)
    del bus.devices[0x76]  # no pressure sensor answers: depth hold and the depth limit need it
    with pytest.raises(BoardStartError, match=r"MS5837-30BA at 0x76 on I²C bus 1: .*"):
        open_pi_board(config, bus=bus, pin_factory=MockFactory())
    assert is_neutral(pulses(bus.snapshot(), [0, 1, 2, 3]))


def test_a_dead_imu_at_start_is_named_and_the_robot_can_be_driven(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # A controller restarted mid-dive (after a failure) with its IMU dead must still drive
    # the robot home: the controller steers by no attitude.
    config = with_controller(example_config(), watchdog_s=MAX_BOARD_WATCHDOG_S)
    bus = fake_bus_for(config)
    del bus.devices[0x28]
    with running_on(config, bus) as rig:
        assert rig.server.board.warnings == (
            "IMU BNO055 at 0x28 not answering: roll, pitch and heading are not measured, qro, "
            "qpi and qhe read 0 until it answers (started again every 1 s)",
        )
        assert any(
            "IMU BNO055 at 0x28 on I²C bus 1" in record.getMessage() and record.levelname == "ERROR"
            for record in caplog.records
        )
        rig.send(b"#debug1!#start!#th.90.50!#qhe!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        assert wait_until(lambda: rig.saw(b"$qhe.0!"))
        assert wait_until(lambda: rig.saw(b"IMU BNO055 at 0x28 stale"))
        assert not rig.server.controller.locked
        assert rig.moving_as_commanded()
    assert not rig.errors


def test_an_imu_that_did_not_start_is_started_again_in_the_background(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    # A BNO055 still booting (about 650 ms after power-on) or hit by a transient error at start
    # was never tried again: the whole session ran without attitude. Now it is started again on
    # a thread of its own (a start takes about a second: never in the control loop), and its
    # attitude is read once it answers; driving is never interrupted.
    config = with_controller(example_config(), watchdog_s=MAX_BOARD_WATCHDOG_S)
    bus = fake_bus_for(config)
    booting = bus.devices.pop(0x28)
    with running_on(config, bus) as rig:
        trying = threading.Event()
        go_on = threading.Event()
        start = Bno055Imu.start

        def slow_start(imu: Bno055Imu) -> None:  # a start that takes as long as the test says
            trying.set()
            assert go_on.wait(CONDITION_TIMEOUT_S)
            start(imu)

        monkeypatch.setattr(Bno055Imu, "start", slow_start)
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        assert trying.wait(CONDITION_TIMEOUT_S), "the IMU was not started again"
        # While a start is under way the control loop runs: it answers and drives.
        rig.send(b"#qhe!")
        assert wait_until(lambda: rig.saw(b"$qhe.0!"))
        assert rig.moving_as_commanded()
        bus.devices[0x28] = booting  # booted
        go_on.set()

        def heading_read() -> bool:
            rig.send(b"#qhe!")
            return wait_until(lambda: rig.saw(b"$qhe.90!"), 0.2)

        assert wait_until(heading_read)
        assert any(
            "IMU BNO055 at 0x28 on I²C bus 1 started after" in record.getMessage()
            for record in caplog.records
        )
        assert not rig.server.controller.locked
        assert rig.moving_as_commanded()
    assert not rig.errors


def _hold_sda_low(bus: FakeI2cBus) -> None:
    """A device reset in the middle of a transfer holds SDA low: nothing gets through."""
    for address in list(bus.devices):
        bus.fail(address, 1 << 30)


def test_a_stuck_bus_in_the_control_loop_is_named_with_what_to_do(
    caplog: pytest.LogCaptureFixture,
) -> None:
    # Before, the loop ended with the bare errno (`Remote I/O error`) and a restart failed the
    # same way for good; now the bus is probed after neutral was tried, and the log and the
    # failure name the bus, its silent devices and the remedy.
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        _hold_sda_low(rig.bus)
        assert wait_until(lambda: bool(rig.errors))
        diagnosis = rig.server.failure_diagnosis
    assert isinstance(rig.errors[0], OSError)
    assert diagnosis is not None
    assert diagnosis.startswith(
        "no device on I²C bus 1 answers (PWM board PCA9685 at 0x40, MS5837 at 0x76): the bus "
        "is stuck (SDA held low"
    )
    assert "power the I²C devices off and on" in diagnosis
    assert "i2cdetect -y 1" in diagnosis
    assert any(
        record.levelname == "ERROR" and diagnosis in record.getMessage()
        for record in caplog.records
    )


def test_one_silent_device_is_told_from_a_stuck_bus() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.bus.fail(PCA_ADDRESS, 1 << 30)
        rig.send(b"#start!#th.90.50!")
        assert wait_until(lambda: bool(rig.errors))
        diagnosis = rig.server.failure_diagnosis
    assert diagnosis == (
        "on I²C bus 1, PWM board PCA9685 at 0x40 does not answer while MS5837 at 0x76 does: "
        "check its wiring and its supply"
    )


def test_a_stuck_bus_at_start_is_named_with_what_to_do() -> None:
    config = _quick()
    bus = fake_bus_for(config)
    _hold_sda_low(bus)
    with pytest.raises(BoardStartError) as raised:
        open_pi_board(config, bus=bus)
    assert str(raised.value).startswith("PWM board PCA9685 at 0x40 on I²C bus 1: ")
    assert "; no device on I²C bus 1 answers (PWM board PCA9685 at 0x40, MS5837 at 0x76)" in (
        str(raised.value)
    )


def test_a_pressure_sensor_with_a_corrupt_prom_is_refused_at_start() -> None:
    config = example_config(imu={"sensor": "none"})
    bus = fake_bus_for(config)
    bus.devices[0x76].prom[3] ^= 0x0100  # type: ignore[attr-defined]
    with pytest.raises(BoardStartError, match=r"MS5837-30BA at 0x76 on I²C bus 1: .*CRC-4"):
        open_pi_board(config, bus=bus)
    assert is_neutral(pulses(bus.snapshot(), [0, 1, 2, 3]))


def test_a_bus_that_does_not_exist_is_named() -> None:
    config = example_config(i2c={"backend": "smbus2", "bus": 250})
    with pytest.raises(BoardStartError, match=r"cannot open I²C bus 250 \(/dev/i2c-250\)"):
        open_pi_board(config)


def test_a_missing_pi_extra_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "smbus2", None)
    config = example_config(i2c={"backend": "smbus2"})
    with pytest.raises(BoardStartError, match=r"smbus2 is missing; pip install 'rovlink\[pi\]'"):
        open_pi_board(config)


def test_the_imu_on_its_own_bus() -> None:
    config = example_config(imu={"bus": 3})
    bus = fake_bus_for(config)
    assert 0x28 not in bus.devices
    board = open_pi_board(config, bus=bus, pin_factory=_mock_pins())
    try:
        imu_sensor = board.sensors[1]
        assert imu_sensor.name == "IMU BNO055 at 0x28"
        assert board.hardware.imu.read_attitude().heading_deg == 90.0
        assert all(t.address != 0x28 for t in bus.snapshot())
    finally:
        board.close()


def _mock_pins() -> object:
    from gpiozero.pins.mock import MockFactory

    return MockFactory()


def test_an_analog_transducer_reads_zero_raw_at_the_surface() -> None:
    config = example_config(
        imu={"sensor": "none"}, pressure={"sensor": "ads1115", "surface_mbar": 0.0}
    )
    board = open_pi_board(config, bus=fake_bus_for(config), pin_factory=_mock_pins())
    try:
        assert board.hardware.pressure.read_raw() == config.controller.depth.zero_raw
        assert board.sensors[0].name == "pressure transducer on ADS1115 at 0x48 AIN0"
    finally:
        board.close()


def test_a_servo_claw_steps_and_holds() -> None:
    config = example_config(
        imu={"sensor": "none"},
        claw={"kind": "servo", "open_us": 2000.0, "close_us": 1000.0, "step_us": 250.0},
    )
    bus = fake_bus_for(config)
    board = open_pi_board(config, bus=bus, pin_factory=_mock_pins())
    try:
        claw = lambda: pulses(bus.snapshot(), [CLAW_CHANNEL])[0]  # noqa: E731
        assert claw() == pytest.approx(1500.0, abs=COUNT_US)  # the start position
        board.hardware.claw.drive(1)
        board.hardware.claw.drive(0)  # the pulse ends: a servo holds
        assert claw() == pytest.approx(1750.0, abs=COUNT_US)
        for _ in range(3):
            board.hardware.claw.drive(1)
        assert claw() == pytest.approx(2000.0, abs=COUNT_US)  # no further than open
        board.hardware.claw.drive(-1)
        assert claw() == pytest.approx(1750.0, abs=COUNT_US)
        board.make_safe()
        assert claw() == pytest.approx(1750.0, abs=COUNT_US)
        assert is_neutral(pulses(bus.snapshot(), [0, 1, 2, 3]))
    finally:
        board.close()


def test_overruns_are_counted_and_logged(caplog: pytest.LogCaptureFixture) -> None:
    import time

    caplog.set_level("WARNING", logger="rovlink.board")
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        sensor = rig.server.board.sensors[0]
        source = sensor._source
        slow_polls = [3]

        class Slow:
            def poll(self, now_s: float) -> int | None:
                if slow_polls[0]:
                    slow_polls[0] -= 1
                    time.sleep(0.025)  # the work of a period takes 2.5 periods
                return source.poll(now_s)

        sensor._source = Slow()
        assert wait_until(lambda: rig.server.schedule.overruns >= 3)
        assert rig.server.schedule.skipped_periods >= 3
    assert any("control loop overran" in record.message for record in caplog.records)


def _chip_pulses(rig: Running) -> list[float | None]:
    """The pulses the fake PCA9685 makes now (a reset is not in the transactions' replay)."""
    chip = rig.bus.devices[0x40]
    assert isinstance(chip, FakePca9685)
    return [chip.pulse_us(channel) for channel in THRUSTER_CHANNELS]


def test_a_pwm_board_reset_is_found_reported_restarted_at_neutral_and_locks() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        chip = rig.bus.devices[0x40]
        assert isinstance(chip, FakePca9685)
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        chip.power_on_reset()  # a supply dip: asleep, every output off
        assert wait_until(lambda: rig.server.controller.locked)
        assert is_neutral(_chip_pulses(rig)), _chip_pulses(rig)
        assert not chip.sleeping
        assert rig.server.device_faults == 1
        assert wait_until(lambda: rig.saw(b"failsafe: PWM board PCA9685 at 0x40 was reset"))
        assert wait_until(lambda: rig.saw(b"motors stopped and locked"))
        # Motion is refused until a host starts the motors again; then it is as commanded.
        rig.send(b"#th.90.50!#qd!")
        assert wait_until(lambda: rig.saw(b"$qd."))
        assert is_neutral(_chip_pulses(rig))
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        assert rig.server.device_faults == 1
    assert not rig.errors


def test_a_pwm_board_reset_while_locked_is_reported_and_repaired() -> None:
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        chip = rig.bus.devices[0x40]
        assert isinstance(chip, FakePca9685)
        rig.send(b"#debug1!")
        chip.power_on_reset()
        assert wait_until(lambda: rig.server.device_faults == 1)
        assert wait_until(lambda: not chip.sleeping and is_neutral(_chip_pulses(rig)))
        assert wait_until(lambda: rig.saw(b"started again, outputs at neutral"))
        assert rig.server.controller.locked
    assert not rig.errors


def test_a_pwm_board_that_fails_its_check_does_not_end_the_loop(
    caplog: pytest.LogCaptureFixture,
) -> None:
    caplog.set_level("INFO", logger="rovlink.board")
    with running(_quick(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        # Locked and still: the only transactions with the chip are the checks' reads.
        rig.bus.fail(0x40, 3)
        assert wait_until(lambda: sum(t.failed for t in rig.bus.snapshot()) == 3)
        assert wait_until(
            lambda: any("answers its check again" in r.getMessage() for r in caplog.records)
        )
        rig.send(b"#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded), rig.pulses()
        assert rig.server.device_faults == 0
    assert not rig.errors
    messages = [record.getMessage() for record in caplog.records]
    # Logged once for the three failures in a row, not once a check.
    assert sum("PCA9685 at 0x40: check failed" in message for message in messages) == 1


def test_the_pwm_board_check_can_be_turned_off() -> None:
    config = _quick()
    config = dataclasses.replace(
        config, pwm_boards=(dataclasses.replace(config.pwm_boards[0], check_interval_s=0.0),)
    )
    board = open_pi_board(config, bus=fake_bus_for(config), pin_factory=_mock_pins())
    try:
        assert board.checks == ()
    finally:
        board.close()


def test_an_imu_reset_is_repaired_before_it_goes_stale() -> None:
    with running(with_controller(example_config(), watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        bno = rig.bus.devices[0x28]
        assert isinstance(bno, FakeBno055)
        rig.send(b"#debug1!#start!#th.90.50!")
        assert wait_until(rig.moving_as_commanded)
        bno.power_on_reset()
        assert wait_until(lambda: rig.saw(b"out of fusion mode (reset?)"))
        imu = rig.server.board.sensors[1]
        assert wait_until(lambda: imu.total_failures >= 1 and imu.failures == 0)
        assert not rig.server.controller.locked  # one failed read: not stale
        assert rig.moving_as_commanded()
        rig.received.clear()
        rig.send(b"#qhe!")
        assert wait_until(lambda: rig.saw(b"$qhe.90!"))
    assert not rig.errors


@contextmanager
def _served_on_tcp(config: PiConfig, silent_client_gives_way_s: float) -> Iterator[Running]:
    """``config``'s board served on TCP only (``Running.fd`` is unused: -1)."""
    from gpiozero.pins.mock import MockFactory

    pins = MockFactory()
    bus = fake_bus_for(config)
    board = open_pi_board(config, bus=bus, pin_factory=pins)
    server = BoardServer(
        config.controller, board, silent_client_gives_way_s=silent_client_gives_way_s
    )
    server.listen_tcp("127.0.0.1", 0)
    stop = threading.Event()
    rig = Running(server, bus, -1, pins)
    thread = threading.Thread(target=server.serve, args=(stop.is_set,), daemon=True)
    thread.start()
    try:
        yield rig
    finally:
        stop.set()
        thread.join(10)
        server.close()
        pins.close()


def _reply(client: socket.socket, query: bytes) -> bytes:
    client.sendall(query)
    return client.recv(100)


def _received_until(client: socket.socket, fragment: bytes) -> bool:
    """Read from ``client`` until ``fragment`` has come (True) or the connection ends."""
    received = b""
    while fragment not in received:
        data = client.recv(4096)
        if not data:
            return False
        received += data
    return True


def test_a_tcp_client_whose_link_died_unseen_gives_way_to_a_new_one() -> None:
    # A station on Wi-Fi that dropped: no FIN ever arrives, the connection stays open. Its
    # motion is stopped by the link-loss failsafe; the station connecting again must get the
    # line, not "busy" for good.
    with _served_on_tcp(_quick(watchdog_s=0.3), silent_client_gives_way_s=0.3) as rig:
        address = rig.server.tcp_address
        assert address is not None
        with socket.create_connection(address, timeout=5) as dead:
            dead.sendall(b"#debug1!#start!#th.90.50!")
            # (Said by the controller rather than caught moving: the motion lasts 0.3 s.)
            assert _received_until(dead, b"failsafe: no valid frame for 0.3 s")
            assert wait_until(rig.neutral)  # the failsafe: the link is silent
            assert wait_until(lambda: rig.server.controller.locked)

            def connected_again() -> bool:
                with socket.create_connection(address, timeout=5) as again:
                    if _reply(again, b"#qd!").startswith(b"$qd."):
                        again.sendall(b"#start!#th.90.50!")
                        # (Its queries keep the motion alive while the test looks.)
                        return wait_until(
                            lambda: (
                                _reply(again, b"#qd!").startswith(b"$qd.")
                                and rig.moving_as_commanded()
                            )
                        )
                    return False

            assert wait_until(connected_again)
    assert not rig.errors


def test_a_tcp_client_that_keeps_its_link_alive_is_not_pushed_out() -> None:
    # (Times far longer than a query and a connection take, even on a loaded machine: the
    # test waits for neither, it only needs each round to come well within them.)
    with _served_on_tcp(_quick(watchdog_s=2.0), silent_client_gives_way_s=2.0) as rig:
        address = rig.server.tcp_address
        assert address is not None
        with socket.create_connection(address, timeout=5) as live:
            live.sendall(b"#start!#th.90.50!")
            assert wait_until(rig.moving_as_commanded)
            for _ in range(10):  # queries faster than the silence that gives way
                assert _reply(live, b"#qd!").startswith(b"$qd.")
                with socket.create_connection(address, timeout=5) as other:
                    assert other.recv(100).startswith(b"busy")
            assert rig.moving_as_commanded()
    assert not rig.errors


#: `#mvdirect.1!#mvs.+50!` on the vertical thrusters of two_pwm_boards_data, channels 0 and 1
#: of the second PWM board: duty +128, vertical_right reversed.
_VERTICAL_UP_50_US = [1500 + 400 * 128 / 255, 1500 - 400 * 128 / 255]


def _on_two_boards(**controller: Any) -> PiConfig:
    return with_controller(pi_config_from_mapping(two_pwm_boards_data(), "rov.toml"), **controller)


def _second_board(rig: Running) -> list[float | None]:
    """The vertical thrusters' pulses and the claw's, on the second PWM board."""
    return pulses(rig.bus.snapshot(), [0, 1, 15], SECOND_PCA_ADDRESS)


def _both_moving(rig: Running) -> bool:
    first = rig.pulses()[:4]
    second = _second_board(rig)[:2]
    expected = TH_90_50_US[:4] + _VERTICAL_UP_50_US
    return all(
        value is not None and abs(value - want) <= COUNT_US
        for value, want in zip(first + second, expected, strict=True)
    )


def _both_neutral(rig: Running) -> bool:
    return is_neutral(rig.pulses()[:4]) and is_neutral(_second_board(rig))


def test_thrusters_on_two_pwm_boards_of_one_bus_move_and_stop_together() -> None:
    with running(_on_two_boards(watchdog_s=0.3)) as rig:
        assert _both_neutral(rig)  # from the start, the claw at rest on the second board too
        move = b"#start!#th.90.50!#mvdirect.1!#mvs.+50!"
        rig.send(move)
        assert wait_until(lambda: _both_moving(rig)), (rig.pulses(), _second_board(rig))
        rig.send(b"#stop!")
        assert wait_until(lambda: _both_neutral(rig)), (rig.pulses(), _second_board(rig))
        rig.send(b"#debug1!" + move)  # and nothing more: the link-loss failsafe stops both
        # (Said by the controller rather than caught moving: the motion lasts 0.3 s.)
        assert wait_until(lambda: rig.saw(b"failsafe: no valid frame for 0.3 s"))
        assert wait_until(lambda: _both_neutral(rig)), (rig.pulses(), _second_board(rig))
        assert rig.server.controller.locked
        assert [check.name for check in rig.server.board.checks] == [
            "PWM board PCA9685 at 0x40",
            "PWM board PCA9685 at 0x41",
        ]
    assert not rig.errors


def test_a_reset_of_the_second_pwm_board_is_found_and_stops_both() -> None:
    with running(_on_two_boards(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        chip = rig.bus.devices[SECOND_PCA_ADDRESS]
        assert isinstance(chip, FakePca9685)
        rig.send(b"#debug1!#start!#th.90.50!#mvdirect.1!#mvs.+50!")
        assert wait_until(lambda: _both_moving(rig))
        chip.power_on_reset()
        assert wait_until(lambda: rig.saw(b"failsafe: PWM board PCA9685 at 0x41 was reset"))
        assert wait_until(lambda: _both_neutral(rig)), (rig.pulses(), _second_board(rig))
        assert not chip.sleeping
        assert rig.server.controller.locked
    assert not rig.errors


def test_a_pwm_board_that_stops_answering_leaves_the_other_at_neutral() -> None:
    with running(_on_two_boards(watchdog_s=MAX_BOARD_WATCHDOG_S)) as rig:
        rig.send(b"#start!#th.90.50!#mvdirect.1!#mvs.+50!")
        assert wait_until(lambda: _both_moving(rig))
        rig.bus.fail(PCA_ADDRESS, 10**6)  # the first board is gone for good
        rig.send(b"#stop!")
        assert wait_until(lambda: bool(rig.errors))
        assert isinstance(rig.errors[0], OSError)
        assert is_neutral(_second_board(rig)[:2]), _second_board(rig)
        assert not rig.server.at_rest  # (the first board's neutral could not be set: said so)


def test_a_pwm_board_that_stops_answering_does_not_keep_the_claw_of_another_running() -> None:
    with running(_on_two_boards(watchdog_s=MAX_BOARD_WATCHDOG_S, claw_pulse_ms=5000)) as rig:
        claw = lambda: _second_board(rig)[2]  # noqa: E731
        rig.send(b"#start!#th.90.50!#mvdirect.1!#mvs.+50!#h+!")
        assert wait_until(lambda: _both_moving(rig))
        assert claw() == pytest.approx(1900.0, abs=COUNT_US)
        rig.bus.fail(PCA_ADDRESS, 10**6)  # the first board is gone for good
        rig.send(b"#stop!")
        assert wait_until(lambda: bool(rig.errors))
        assert claw() == pytest.approx(1500.0, abs=COUNT_US)


def test_neutral_from_another_process_reaches_every_pwm_board() -> None:
    # systemd's ExecStopPost after a controller killed with both boards driving.
    config = _on_two_boards()
    bus = fake_bus_for(config)
    board = open_pi_board(config, bus=bus, pin_factory=_mock_pins())
    try:
        board.hardware.thrusters.set_duties([128] * 6)
    finally:
        board.close()
    assert not is_neutral(pulses(bus.snapshot(), [0, 1], SECOND_PCA_ADDRESS))
    bus.fail(PCA_ADDRESS, 10**6)
    with pytest.raises(BoardStartError) as caught:
        set_pi_outputs_at_rest(config, bus=bus)
    assert str(caught.value).startswith("PWM board PCA9685 at 0x40 on I²C bus 1: ")
    assert "done: PWM board PCA9685 at 0x41 on I²C bus 1 (running): neutral pulses" in str(
        caught.value
    )
    assert is_neutral(pulses(bus.snapshot(), [0, 1], SECOND_PCA_ADDRESS))
    bus.fail(PCA_ADDRESS, 0)
    done = set_pi_outputs_at_rest(config, bus=bus)
    assert done.count("neutral pulses on channels") == 2
    assert is_neutral(pulses(bus.snapshot(), [0, 1, 2, 3]))


@pytest.mark.parametrize(
    ("watchdog_s", "reason"),
    [
        (0.0, "got 0, which turns the link-loss failsafe off (P17)"),
        (3600.0, "got 3600: a dead link would leave the thrusters running that long"),
    ],
)
def test_a_board_is_never_served_without_a_link_loss_failsafe(
    watchdog_s: float, reason: str
) -> None:
    # watchdog_s = 0, handy on the simulator's bench, on a robot leaves a dead link's last
    # command running: the board loop refuses it even from a config its file checks skipped.
    config = _quick(watchdog_s=watchdog_s)
    board = open_pi_board(config, bus=fake_bus_for(config), pin_factory=_mock_pins())
    try:
        with pytest.raises(ValueError, match=r"watchdog_s must be 0\.1–10 s on a robot") as caught:
            BoardServer(config.controller, board)
    finally:
        board.close()
    assert reason in str(caught.value)
