"""Pressure onto the protocol's raw scale, and the ADS1115 with an analog transducer."""

from __future__ import annotations

import contextlib

import pytest

from rovlink.board.board import BoardStartError
from rovlink.board.pi.ads1115 import Ads1115, config_word
from rovlink.board.pi.board import fake_bus_for, open_pi_board
from rovlink.board.pi.fake_bus import (
    MS5837_EXAMPLES,
    FakeAds1115,
    FakeI2cBus,
    FakeMs5837,
    ms5837_prom,
)
from rovlink.board.pi.ms5837 import Ms5837, Ms5837Model
from rovlink.board.pi.pressure import (
    FULL_SCALE_MBAR,
    AnalogPressure,
    AnalogTransducer,
    Ms5837Pressure,
    RawScale,
)
from rovlink.board.sensors import SensorError
from rovlink.controller import Controller
from tests.board.rig import example_config, is_neutral, pulses, wait_until


def test_the_raw_scale_gives_the_controllers_depth_back() -> None:
    scale = RawScale(zero_raw=20, k=200, surface_mbar=1013.25, density_kg_m3=997.0)
    # 3 m of fresh water: 3 × 997 × 9.80665 Pa = 293.3 mbar.
    raw = scale.raw(1013.25 + 3 * 997.0 * 9.80665 / 100)
    assert raw == 170  # 20 + 300 cm / 2 cm per count
    # P13 with the same zero and k: (raw − zero) · k / 100 cm.
    assert (raw - 20) * 200 // 100 == 300
    assert scale.raw(0.0) == 0  # clipped as an ADC clips
    assert scale.raw(100_000.0) == 1024


def test_a_raw_scale_of_k_0_is_refused_not_a_division_by_zero() -> None:
    with pytest.raises(ValueError, match="raw scale: k must be ≥ 1"):
        RawScale(zero_raw=20, k=0, surface_mbar=1013.25, density_kg_m3=997.0)


def test_sdk_0_zeroes_the_controllers_depth_and_leaves_the_boards_raw_scale() -> None:
    """The protocol allows `#sdk.0!`: the controller multiplies by k, so every depth reads 0;
    the board's raw scale keeps rov.toml's k, so nothing divides by 0 and `qr` still reads."""
    config = example_config(
        imu={"sensor": "none"},
        leak={"pin": -1},
        pressure={"sensor": "ads1115", "surface_mbar": 0.0},
    )
    ads = config.pressure.ads1115
    bus = fake_bus_for(config)
    adc = bus.devices[ads.address]
    assert isinstance(adc, FakeAds1115)
    board = open_pi_board(config, bus=bus)
    try:
        controller = Controller(config.controller, board.hardware)
        one_metre_mbar = 997.0 * 9.80665 / 100
        fraction = (one_metre_mbar - ads.min_mbar) / (ads.max_mbar - ads.min_mbar)
        adc.volts = ads.min_volts + fraction * (ads.max_volts - ads.min_volts)
        assert board.sensors[0].poll(0.0) is None
        controller.receive(b"#qr!#qd!")
        assert controller.read_output() == b"$qr.70!$qd.100!"  # 1 m, 2 cm a count
        controller.receive(b"#sdk.0!")
        assert board.sensors[0].poll(0.01) is None
        controller.tick()
        controller.receive(b"#qr!#qd!")
        assert controller.read_output() == b"$qr.70!$qd.0!"
    finally:
        board.close()


@pytest.mark.parametrize("ads1115_table", ["the example's", "the defaults"])
def test_a_transducer_wired_as_documented_reads_its_pressure(ads1115_table: str) -> None:
    """docs/hardware.md: a 0.5–4.5 V transducer (0–10 bar) through 10 kΩ over 20 kΩ, so the
    ADS1115 on 3.3 V sees 0.33–3.0 V; rov.toml's [pressure.ads1115] as given must read it."""
    pressure: dict[str, object] = {"sensor": "ads1115", "surface_mbar": 0.0}
    if ads1115_table == "the defaults":
        pressure["ads1115"] = {}
    config = example_config(imu={"sensor": "none"}, leak={"pin": -1}, pressure=pressure)
    bus = fake_bus_for(config)
    adc = bus.devices[config.pressure.ads1115.address]
    assert isinstance(adc, FakeAds1115)
    board = open_pi_board(config, bus=bus)
    try:
        three_metres_mbar = 3 * 997.0 * 9.80665 / 100
        transducer_volts = 0.5 + 4.0 * three_metres_mbar / 10000.0
        adc.volts = transducer_volts * 20 / (10 + 20)
        assert board.sensors[0].poll(0.0) is None
        assert board.hardware.pressure.read_raw() == 170  # 20 + 300 cm at 2 cm a count
    finally:
        board.close()


def test_ads1115_config_word_follows_the_datasheet() -> None:
    # OS 0, MUX 100 (AIN0–GND), PGA 001 (±4.096 V), MODE 0 (continuous), DR 100 (128 SPS),
    # comparator disabled (11).
    assert config_word(0, 4.096, 128) == 0b0_100_001_0_100_0_0_0_11
    assert config_word(3, 6.144, 860) >> 12 == 0b111


def test_an_analog_transducer_through_the_ads1115() -> None:
    fake = FakeAds1115(volts=2.5)
    bus = FakeI2cBus({0x48: fake})
    adc = Ads1115(bus, full_scale_v=6.144, data_rate_sps=860)
    adc.start()
    assert bus.transactions[0].written == bytes(
        [0x01, *config_word(0, 6.144, 860).to_bytes(2, "big")]
    )
    assert adc.read_volts() == pytest.approx(2.5, abs=0.001)
    transducer = AnalogTransducer(min_volts=0.5, max_volts=4.5, min_mbar=0.0, max_mbar=4000.0)
    pressure = AnalogPressure(adc, transducer, RawScale(20, 200, 0.0, 1000.0))
    raw = pressure.poll(0.0)
    assert pressure.last_mbar == pytest.approx(2000.0, abs=1.0)
    assert raw == 1024  # 20 m of a gauge transducer: past the raw scale's 0–20 m


def test_a_disconnected_transducer_is_a_fault_not_a_depth() -> None:
    fake = FakeAds1115(volts=0.0)
    adc = Ads1115(FakeI2cBus({0x48: fake}), data_rate_sps=860)
    adc.start()
    pressure = AnalogPressure(adc, AnalogTransducer(), RawScale(20, 200, 0.0, 1000.0))
    with pytest.raises(SensorError, match="disconnected or faulty"):
        pressure.poll(0.0)


def _mbar_at(depth_m: float, surface_mbar: float = 1013.25, density_kg_m3: float = 997.0) -> float:
    """The absolute pressure ``depth_m`` below the surface."""
    return surface_mbar + depth_m * density_kg_m3 * 9.80665 / 100


@pytest.mark.parametrize("model", ["30ba", "02ba"])
@pytest.mark.parametrize("temperature_c", [20.0, 4.0])
def test_the_depth_of_the_fake_ms5837_through_the_board_and_the_controller(
    model: str, temperature_c: float
) -> None:
    """From the MS5837's raw conversions to `qd`: the surface reads 0 cm at zero_raw, 2.5 m
    reads 250 cm at 20 + 125 counts of 2 cm (the example's [depth] zero 20, k 200)."""
    config = example_config(
        imu={"sensor": "none"}, leak={"pin": -1}, pressure={"ms5837": {"model": model}}
    )
    bus = fake_bus_for(config)
    fake = bus.devices[0x76]
    assert isinstance(fake, FakeMs5837)
    board = open_pi_board(config, bus=bus)
    try:
        controller = Controller(config.controller, board.hardware)
        sensor = board.sensors[0]
        clock = board.hardware.clock

        def reads(raw: int) -> bool:
            sensor.poll(clock.now_s())
            return board.hardware.pressure.read_raw() == raw

        # The fake sits at the surface of rov.toml, 20 °C: a dry run's depth is 0.
        controller.receive(b"#qr!#qd!")
        assert controller.read_output() == b"$qr.20!$qd.0!"
        fake.set_reading(_mbar_at(2.5), temperature_c)
        assert wait_until(lambda: reads(145), timeout_s=2.0)
        controller.receive(b"#qr!#qd!")
        assert controller.read_output() == b"$qr.145!$qd.250!"
        fake.set_reading(_mbar_at(0.0), temperature_c)
        assert wait_until(lambda: reads(20), timeout_s=2.0)
        controller.receive(b"#qd!")
        assert controller.read_output() == b"$qd.0!"
    finally:
        board.close()


def test_a_bar30_configured_as_a_bar02_is_refused_at_start_not_read_as_the_surface() -> None:
    """A PROM whose product version names no model (this fake's) cannot tell the models
    apart, and the 02BA's compensation makes a 30BA's 1013 mbar about 51 mbar: raw 0, `qd` 0
    at any depth, a depth hold pushing down for ever.
    No air or water is below 300 mbar, so such a reading is a fault, never a depth."""
    config = example_config(
        imu={"sensor": "none"}, leak={"pin": -1}, pressure={"ms5837": {"model": "02ba"}}
    )
    bus = fake_bus_for(config)
    bus.devices[0x76] = FakeMs5837.reading(Ms5837Model.BA30, 1013.25)
    with pytest.raises(
        BoardStartError,
        match=r"MS5837-02BA at 0x76 on I²C bus 1: no reading at start: it reads 50\.\d+ mbar, "
        r"below any "
        r"air or water \(300 mbar\): is \[pressure\.ms5837\] model right\? "
        r"\(30ba: Bar30, 02ba: Bar02\)",
    ):
        open_pi_board(config, bus=bus)
    assert is_neutral(pulses(bus.snapshot()))


def test_a_bar02_whose_prom_names_it_is_refused_at_start_as_a_bar30() -> None:
    """Computed as a 30BA, an 02BA's 1013 mbar reads about 20 bar, a plausible depth: no
    reading shows the mistake. An MS5837-02BA21 names itself in its PROM (product version 21 in
    word 0's bits 11–5), so it is refused at start, naming the key to set."""
    config = example_config(imu={"sensor": "none"}, leak={"pin": -1})  # model = "30ba"
    coefficients, d1, d2 = MS5837_EXAMPLES[Ms5837Model.BA02]
    fake = FakeMs5837(ms5837_prom(coefficients, factory_bits=21 << 5), d1, d2, Ms5837Model.BA02)
    fake.set_reading(1013.25)
    bus = fake_bus_for(config)
    bus.devices[0x76] = fake
    with pytest.raises(
        BoardStartError,
        match=r"^pressure sensor MS5837-30BA at 0x76 on I²C bus 1: MS5837 at 0x76: its PROM "
        r"names it an MS5837-02BA21 \(product version 0x15 in word 0\), not the 30ba it is "
        r'set to be: set \[pressure\.ms5837\] model = "02ba"$',
    ):
        open_pi_board(config, bus=bus)
    assert is_neutral(pulses(bus.snapshot()))


def test_an_implausible_pressure_while_running_is_a_failed_read() -> None:
    config = example_config(imu={"sensor": "none"}, leak={"pin": -1})
    bus = fake_bus_for(config)
    fake = bus.devices[0x76]
    assert isinstance(fake, FakeMs5837)
    board = open_pi_board(config, bus=bus)
    try:
        sensor = board.sensors[0]
        clock = board.hardware.clock
        fake.set_reading(250.0)
        assert wait_until(
            lambda: isinstance(sensor.poll(clock.now_s()), SensorError), timeout_s=2.0
        )
        assert sensor.value == config.controller.depth.zero_raw  # the last good value
        fake.set_reading(_mbar_at(1.0))
        assert wait_until(lambda: (sensor.poll(clock.now_s()), sensor.value)[1] == 70, 2.0)
        assert sensor.failures == 0
    finally:
        board.close()


class _SteppedClock:
    """A clock the test moves."""

    def __init__(self) -> None:
        self.now = 0.0

    def now_s(self) -> float:
        return self.now


def _next_raw(pressure: Ms5837Pressure, clock: _SteppedClock) -> int:
    """Step the clock a control period at a time until a D1–D2 pair completes; its raw value
    (or the SensorError it gives)."""
    for _ in range(10):
        clock.now += 0.01
        raw = pressure.poll(clock.now)
        if raw is not None:
            return raw
    raise AssertionError("no reading in ten periods")


def _settled_raw(pressure: Ms5837Pressure, clock: _SteppedClock) -> int:
    """The raw value of the first D1 converted after a change to the fake (the one under way
    at the change was latched before it)."""
    with contextlib.suppress(SensorError):
        _next_raw(pressure, clock)
    return _next_raw(pressure, clock)


@pytest.mark.parametrize("model", list(Ms5837Model))
def test_a_corrupt_pressure_conversion_past_the_sensors_range_is_a_failed_read(
    model: Ms5837Model,
) -> None:
    # A D1 read as all ones (a bus glitch) with a good D2: the temperature is plausible, the
    # pressure tens of bar, which the raw scale clipped to its deepest reading: a depth hold
    # answered it with full up thrust. Now it is a failed read, as one below any air or water.
    fake = FakeMs5837.reading(model, _mbar_at(1.0))
    clock = _SteppedClock()
    sensor = Ms5837(FakeI2cBus({0x76: fake}), model=model, clock=clock)
    sensor.start()
    pressure = Ms5837Pressure(sensor, RawScale(20, 200, 1013.25, 997.0))
    assert _next_raw(pressure, clock) == 70  # 1 m down: 50 counts of 2 cm past zero_raw 20
    fake.d1 = 0xFFFFFF
    full_scale = f"{FULL_SCALE_MBAR[model]:g}"
    with pytest.raises(SensorError, match=rf"past the {full_scale} mbar range of an MS5837-"):
        _settled_raw(pressure, clock)
    assert pressure.last_mbar == pytest.approx(_mbar_at(1.0), abs=0.1)  # the last good one
    fake.set_reading(FULL_SCALE_MBAR[model])  # the top of its range is a reading
    assert _settled_raw(pressure, clock) == RawScale(20, 200, 1013.25, 997.0).raw(
        FULL_SCALE_MBAR[model]
    )


def test_an_ads1115_reset_by_a_supply_dip_is_started_again() -> None:
    """After a reset the converter is powered down and reads 0 V: a fault for ever, and the
    stale-sensor failsafe would keep the motors stopped until the controller is restarted."""
    fake = FakeAds1115(volts=2.5)
    bus = FakeI2cBus({0x48: fake})
    adc = Ads1115(bus, full_scale_v=6.144, data_rate_sps=860)
    adc.start()
    transducer = AnalogTransducer(min_volts=0.5, max_volts=4.5, min_mbar=0.0, max_mbar=4000.0)
    pressure = AnalogPressure(adc, transducer, RawScale(20, 200, 0.0, 1000.0))
    assert pressure.poll(0.0) == 1024
    fake.power_on_reset()
    with pytest.raises(SensorError, match=r"ADS1115 at 0x48 was reset \(config 0x8583\)"):
        pressure.poll(0.01)
    assert bus.transactions[-1].written == bytes(
        [0x01, *config_word(0, 6.144, 860).to_bytes(2, "big")]
    )
    assert pressure.poll(0.02) == 1024
    # A transducer that is really disconnected is not taken for a reset: no write.
    fake.volts = 0.0
    before = len(bus.transactions)
    with pytest.raises(SensorError, match="disconnected or faulty"):
        pressure.poll(0.03)
    assert all(len(t.written) == 1 for t in bus.transactions[before:])


@pytest.mark.parametrize("min_volts", [0.0, 0.1])
def test_an_ads1115_reset_is_found_when_0_v_is_inside_the_transducers_range(
    min_volts: float,
) -> None:
    """A transducer whose range starts at (or within 5 % of) 0 V takes a reset converter's 0 V
    for its lowest pressure: the depth read the surface at any depth, and depth hold drove the
    robot down. A conversion of 0 is read back as a possible reset too."""
    fake = FakeAds1115(volts=2.0)
    bus = FakeI2cBus({0x48: fake})
    adc = Ads1115(bus, full_scale_v=4.096, data_rate_sps=860)
    adc.start()
    transducer = AnalogTransducer(min_volts=min_volts, max_volts=3.0, max_mbar=4000.0)
    scale = RawScale(20, 200, 0.0, 1000.0)
    pressure = AnalogPressure(adc, transducer, scale)
    deep = pressure.poll(0.0)
    fake.power_on_reset()
    with pytest.raises(SensorError, match=r"ADS1115 at 0x48 was reset \(config 0x8583\)"):
        pressure.poll(0.01)
    assert pressure.poll(0.02) == deep  # converting again
    # A conversion of 0 from a converter that runs is a reading (one more register read).
    fake.volts = 0.0
    assert pressure.poll(0.03) == scale.raw(transducer.mbar(0.0))
    assert not any(len(t.written) > 1 for t in bus.transactions[-2:])  # no config written
