"""The BNO055 through Adafruit's driver on the fake bus, and the leak probe on gpiozero's mock
pin factory."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from rovlink.board.pi.bno055 import Bno055Imu, remap_for_placement
from rovlink.board.pi.board import fake_bus_for, open_pi_board
from rovlink.board.pi.fake_bus import FakeBno055, FakeI2cBus
from rovlink.board.pi.leak import GpioLeakSensor
from rovlink.board.sensors import SensorError
from rovlink.controller import Controller
from tests.board.rig import example_config


def _started(imu_args: dict[str, object] | None = None) -> tuple[FakeBno055, FakeI2cBus, Bno055Imu]:
    fake = FakeBno055(roll_deg=12.5, pitch_deg=-3.0, heading_deg=350.0)
    bus = FakeI2cBus({0x28: fake})
    imu = Bno055Imu(bus, **(imu_args or {}))  # type: ignore[arg-type]
    imu.start()
    return fake, bus, imu


def test_fused_attitude_through_the_maintained_driver() -> None:
    fake, _bus, imu = _started()
    assert fake.registers[0x3D] == 0x0C  # NDOF fusion mode, set by Adafruit's driver
    attitude = imu.poll(0.0)
    assert attitude is not None
    assert (attitude.roll_deg, attitude.pitch_deg, attitude.heading_deg) == (12.5, -3.0, 350.0)
    assert imu.poll(0.01) is None  # 20 Hz: the next read is due at 0.05 s
    assert imu.poll(0.05) is not None


def test_mounting_signs_and_heading_offset() -> None:
    fake, _, imu = _started(
        {"placement": "P0", "invert_roll": True, "invert_pitch": True, "heading_offset_deg": 20.0}
    )
    # P0 of the datasheet's table 3-5: AXIS_MAP_CONFIG 0x21, AXIS_MAP_SIGN 0x04.
    assert (fake.registers[0x41], fake.registers[0x42]) == (0x21, 0x04)
    attitude = imu.poll(0.0)
    assert attitude is not None
    assert (attitude.roll_deg, attitude.pitch_deg) == (-12.5, 3.0)
    assert attitude.heading_deg == pytest.approx(10.0)  # 350 + 20, wrapped


def test_every_placement_maps_each_axis_once() -> None:
    for placement in [f"P{n}" for n in range(8)]:
        x, y, z, *_ = remap_for_placement(placement)
        assert sorted((x, y, z)) == [0, 1, 2], placement


def test_an_attitude_that_is_not_a_number_is_a_sensor_error() -> None:
    fake, _, imu = _started()
    fake.registers[0x3D] = 0x00  # the chip fell back to config mode: the driver gives None
    with pytest.raises(SensorError, match="BNO055 at 0x28: out of fusion mode"):
        imu.poll(0.0)


def test_an_attitude_outside_the_datasheets_ranges_is_a_corrupt_read() -> None:
    fake, _, imu = _started()  # (one chip for every case: its start takes 0.7 s)
    # The datasheet's ranges (table 3-13): heading 0–360°, roll ±90°, pitch ±180°. A heading of
    # −100° (raw −1600) would have passed as 260° once wrapped.
    cases = [
        (2.0, -1.0, -100.0),
        (90.0625, -1.0, 90.0),
        (-90.0625, -1.0, 90.0),
        (2.0, 180.0625, 90.0),
        (2.0, -180.0625, 90.0),
        (2.0, -1.0, 360.0625),
    ]
    for number, (roll_deg, pitch_deg, heading_deg) in enumerate(cases):
        fake.set_attitude(roll_deg, pitch_deg, heading_deg)
        with pytest.raises(SensorError, match=r"BNO055 at 0x28: heading .* a corrupt read"):
            imu.poll(float(number))
    fake.set_attitude(90.0, -180.0, 360.0)  # the ranges' ends are attitudes
    attitude = imu.poll(10.0)
    assert attitude is not None
    assert (attitude.roll_deg, attitude.pitch_deg, attitude.heading_deg) == (90.0, -180.0, 0.0)


def test_a_bno055_reset_is_put_back_into_fusion_with_its_placement() -> None:
    """A reset (a supply dip, the chip's own watchdog) brings the chip back in config mode with
    the default axis map: no attitude, for ever, and the stale-IMU failsafe would keep the motors
    stopped until the controller is restarted."""
    fake, bus, imu = _started({"placement": "P0", "invert_roll": True})
    assert imu.poll(0.0) is not None
    fake.power_on_reset()
    with pytest.raises(SensorError, match=r"out of fusion mode \(reset\?\): fusion mode and"):
        imu.poll(0.05)
    assert fake.registers[0x3D] == 0x0C  # NDOF again
    assert (fake.registers[0x41], fake.registers[0x42]) == (0x21, 0x04)  # P0 again
    attitude = imu.poll(0.1)
    assert attitude is not None
    assert (attitude.roll_deg, attitude.pitch_deg, attitude.heading_deg) == (-12.5, -3.0, 350.0)
    assert imu.fusion_restarts == 1
    # A chip that falls out again at once is put back at most once a second: a failing chip
    # must not cost the control loop 60 ms of mode changes every poll.
    fake.power_on_reset()
    before = len(bus.transactions)
    with pytest.raises(SensorError, match=r"out of fusion mode$"):
        imu.poll(0.2)
    assert all(not t.written or len(t.written) == 1 for t in bus.transactions[before:])  # reads
    with pytest.raises(SensorError, match="set again"):
        imu.poll(1.2)
    assert imu.poll(1.3) is not None
    assert imu.fusion_restarts == 2


@pytest.fixture
def mock_factory() -> Iterator[object]:
    from gpiozero.pins.mock import MockFactory

    factory = MockFactory()
    yield factory
    factory.close()


def test_a_one_millisecond_leak_pulse_is_latched(mock_factory: object) -> None:
    leak = GpioLeakSensor(27, active_high=True, pull="down", pin_factory=mock_factory)
    pin = mock_factory.pin(27)  # type: ignore[attr-defined]
    assert leak.fired_since_last_read() is False
    # A pulse of 1 ms: wet, then dry again, both before the controller's next 10 ms tick.
    pin.drive_high()
    pin.drive_low()
    assert leak.fired_since_last_read() is True
    assert leak.fired_since_last_read() is False  # read once, cleared
    leak.close()


def test_an_active_low_probe_that_stays_wet(mock_factory: object) -> None:
    leak = GpioLeakSensor(17, active_high=False, pull="up", pin_factory=mock_factory)
    pin = mock_factory.pin(17)  # type: ignore[attr-defined]
    assert leak.fired_since_last_read() is False  # the pull-up holds it high: dry
    pin.drive_low()
    assert leak.fired_since_last_read() is True
    assert leak.fired_since_last_read() is True  # still wet: reported again
    pin.drive_high()
    assert leak.fired_since_last_read() is False
    leak.close()


def test_a_pull_against_the_polarity_is_refused(mock_factory: object) -> None:
    with pytest.raises(ValueError, match="pull-down input rests low"):
        GpioLeakSensor(22, active_high=False, pull="down", pin_factory=mock_factory)


def test_attitude_ties_from_the_bno055_to_the_replies() -> None:
    """P15: whole degrees rounded to nearest; it leaves a tie open. The chip's 1/16° steps reach
    the controller exactly, and a tie (x.5°) goes up, toward +∞, as docs/hardware.md says."""
    config = example_config(leak={"pin": -1})
    bus = fake_bus_for(config)
    bno = bus.devices[0x28]
    assert isinstance(bno, FakeBno055)
    board = open_pi_board(config, bus=bus)
    try:
        controller = Controller(config.controller, board.hardware)
        imu = board.sensors[1]
        start_s = board.hardware.clock.now_s()
        cases = [
            ((2.5, -2.5, 359.5), b"$qro.+3!$qpi.-2!$qhe.0!"),
            ((-0.5, 0.5, 0.5), b"$qro.+0!$qpi.+1!$qhe.1!"),
            ((89.5, -90.5, 179.5), b"$qro.+90!$qpi.-90!$qhe.180!"),
            # One of the chip's steps either side of a tie.
            ((2.4375, -2.5625, 359.4375), b"$qro.+2!$qpi.-3!$qhe.359!"),
            ((2.5625, -2.4375, 0.5625), b"$qro.+3!$qpi.-2!$qhe.1!"),
        ]
        for number, ((roll_deg, pitch_deg, heading_deg), replies) in enumerate(cases, 1):
            bno.set_attitude(roll_deg, pitch_deg, heading_deg)
            assert imu.poll(start_s + number) is None  # read without an error
            assert imu.value == (roll_deg, pitch_deg, heading_deg)  # exactly, no rounding yet
            controller.receive(b"#qro!#qpi!#qhe!")
            assert controller.read_output() == replies, (roll_deg, pitch_deg, heading_deg)
    finally:
        board.close()


def test_a_leak_pulse_while_the_probe_starts_is_latched(
    mock_factory: object, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A pulse between the edge callback's start and the driver's first look at the pin: the
    callback latches it, and the look at a dry pin must not clear it (P14: however short the
    pulse)."""
    import gpiozero

    class PulsedOnFirstLook(gpiozero.DigitalInputDevice):  # type: ignore[misc]
        looked = False

        @property
        def is_active(self) -> bool:
            if self.when_activated is not None and not PulsedOnFirstLook.looked:
                PulsedOnFirstLook.looked = True
                pin = mock_factory.pin(27)  # type: ignore[attr-defined]
                pin.drive_high()
                pin.drive_low()
            return bool(super().is_active)

    monkeypatch.setattr(gpiozero, "DigitalInputDevice", PulsedOnFirstLook)
    leak = GpioLeakSensor(27, active_high=True, pull="down", pin_factory=mock_factory)
    assert PulsedOnFirstLook.looked
    assert leak.fired_since_last_read() is True
    leak.close()
