"""The MS5837 driver against the datasheets' example calibration and conversions."""

from __future__ import annotations

import pytest

from rovlink.board.pi.fake_bus import (
    MS5837_EXAMPLES,
    FakeDevice,
    FakeI2cBus,
    FakeMs5837,
    ms5837_prom,
)
from rovlink.board.pi.ms5837 import (
    Ms5837,
    Ms5837Model,
    Ms5837Reading,
    compensate,
    crc4,
    product_version,
)
from rovlink.board.sensors import SensorError


class _TimedBus(FakeI2cBus):
    """The fake bus on a fake clock (its :meth:`now_s`): each transaction takes
    ``transaction_s``, and ``started_s`` notes when each began (one per transaction)."""

    def __init__(self, devices: dict[int, FakeDevice], transaction_s: float = 0.0) -> None:
        super().__init__(devices)
        self.time_s = 0.0
        self.transaction_s = transaction_s
        self.started_s: list[float] = []

    def now_s(self) -> float:
        return self.time_s

    def write(self, address: int, data: bytes) -> None:
        self._elapse()
        super().write(address, data)

    def read(self, address: int, length: int) -> bytes:
        self._elapse()
        return super().read(address, length)

    def write_read(self, address: int, data: bytes, length: int) -> bytes:
        self._elapse()
        return super().write_read(address, data, length)

    def _elapse(self) -> None:
        self.started_s.append(self.time_s)
        self.time_s += self.transaction_s


def _sensor(
    model: Ms5837Model, fake: FakeMs5837 | None = None, *, transaction_s: float = 0.0
) -> tuple[FakeMs5837, Ms5837, _TimedBus]:
    fake = fake if fake is not None else FakeMs5837.example(model)
    bus = _TimedBus({0x76: fake}, transaction_s)
    sensor = Ms5837(bus, model=model, oversampling=4096, clock=bus)
    return fake, sensor, bus


def _poll_at(sensor: Ms5837, bus: _TimedBus, now_s: float) -> Ms5837Reading | None:
    """A period that starts at ``now_s`` (or when the bus is free, if later) polls the sensor."""
    bus.time_s = max(bus.time_s, now_s)
    return sensor.poll(bus.time_s)


@pytest.mark.parametrize(
    ("model", "pressure_mbar", "temperature_c"),
    [
        # The datasheets' examples: MS5837-30BA 3999.8 mbar at 19.81 °C (P = 39998 in 0.1 mbar,
        # TEMP = 1981 in 0.01 °C); MS5837-02BA 1100.02 mbar at 20.00 °C.
        (Ms5837Model.BA30, 3999.8, 19.81),
        (Ms5837Model.BA02, 1100.02, 20.00),
    ],
)
def test_first_order_compensation_gives_the_datasheet_example(
    model: Ms5837Model, pressure_mbar: float, temperature_c: float
) -> None:
    coefficients, d1, d2 = MS5837_EXAMPLES[model]
    prom = [0, *coefficients]
    reading = compensate(model, prom, d1, d2, second_order=False)
    assert reading.pressure_mbar == pytest.approx(pressure_mbar, abs=1e-9)
    assert reading.temperature_c == pytest.approx(temperature_c, abs=1e-9)


def test_the_02ba_second_order_terms_vanish_at_20_degrees() -> None:
    coefficients, d1, d2 = MS5837_EXAMPLES[Ms5837Model.BA02]
    prom = [0, *coefficients]
    first = compensate(Ms5837Model.BA02, prom, d1, d2, second_order=False)
    assert compensate(Ms5837Model.BA02, prom, d1, d2) == first


def test_second_order_compensation_in_cold_water() -> None:
    # The 30BA example's sensor at about 4 °C: D2 lowered so that TEMP < 2000.
    coefficients, d1, _ = MS5837_EXAMPLES[Ms5837Model.BA30]
    c1, c2, c3, c4, c5, c6 = coefficients
    prom = [0, *coefficients]
    d2 = 6_300_000
    dt = d2 - c5 * 256
    temp = 2000 + dt * c6 // 2**23
    assert temp < 2000
    # The datasheet's low-temperature branch, written out.
    ti = 3 * dt * dt // 2**33
    offi = 3 * (temp - 2000) ** 2 // 2
    sensi = 5 * (temp - 2000) ** 2 // 8
    off = c2 * 2**16 + c4 * dt // 2**7 - offi
    sens = c1 * 2**15 + c3 * dt // 2**8 - sensi
    expected_mbar = ((d1 * sens // 2**21 - off) // 2**13) / 10
    reading = compensate(Ms5837Model.BA30, prom, d1, d2)
    assert reading.temperature_c == (temp - ti) / 100
    assert reading.pressure_mbar == expected_mbar
    assert reading != compensate(Ms5837Model.BA30, prom, d1, d2, second_order=False)


def test_start_resets_and_reads_a_prom_whose_crc_checks() -> None:
    fake, sensor, _bus = _sensor(Ms5837Model.BA30)
    sensor.start()
    assert fake.resets == 1
    assert list(sensor.prom) == fake.prom
    assert sensor.prom[0] >> 12 == crc4(sensor.prom)


@pytest.mark.parametrize("word", range(1, 7))
def test_a_prom_with_a_bad_crc4_is_refused(word: int) -> None:
    model = Ms5837Model.BA30
    fake = FakeMs5837.example(model)
    fake.prom[word] ^= 0x0010  # one bit of one calibration word
    _, sensor, _bus = _sensor(model, fake)
    with pytest.raises(SensorError, match="CRC-4"):
        sensor.start()


@pytest.mark.parametrize("word", [0x0000, 0xFFFF])
def test_a_prom_that_reads_the_same_word_everywhere_is_refused_as_no_calibration(
    word: int,
) -> None:
    # Seven zero words pass the CRC-4 (its remainder over zeros is 0): the sensor would start
    # and read 0 mbar, blamed on the model setting. Seven 0xFFFF words fail it, as "corrupt".
    assert crc4([0x0000] * 7) == 0
    model = Ms5837Model.BA30
    _, d1, d2 = MS5837_EXAMPLES[model]
    _, sensor, _bus = _sensor(model, FakeMs5837([word] * 7, d1, d2, model))
    with pytest.raises(SensorError, match=f"0x76: every PROM word reads {word:#06x}, no calib"):
        sensor.start()
    assert sensor.prom == ()


def _prom_with_version(model: Ms5837Model, version: int) -> list[int]:
    """The datasheet's example calibration, with ``version`` in word 0's bits 11–5 (its bits
    4–0, factory data, at 0b10110) and the CRC-4 made to fit."""
    return ms5837_prom(MS5837_EXAMPLES[model][0], factory_bits=version << 5 | 0b10110)


@pytest.mark.parametrize(
    ("fitted", "version", "configured", "part"),
    [
        # The datasheets' fixed product versions: 0011010 for the MS5837-30BA26 (a Bar30),
        # 0010101 (21) for the MS5837-02BA21.
        (Ms5837Model.BA30, 0b0011010, Ms5837Model.BA02, "MS5837-30BA26"),
        (Ms5837Model.BA02, 0b0010101, Ms5837Model.BA30, "MS5837-02BA21"),
    ],
)
def test_a_model_its_prom_contradicts_is_refused_naming_the_part_and_the_key(
    fitted: Ms5837Model, version: int, configured: Ms5837Model, part: str
) -> None:
    _, d1, d2 = MS5837_EXAMPLES[fitted]
    fake = FakeMs5837(_prom_with_version(fitted, version), d1, d2, fitted)
    _, sensor, _bus = _sensor(configured, fake)
    with pytest.raises(SensorError) as raised:
        sensor.start()
    assert str(raised.value) == (
        f"MS5837 at 0x76: its PROM names it an {part} (product version {version:#04x} in word "
        f'0), not the {configured} it is set to be: set [pressure.ms5837] model = "{fitted}"'
    )


@pytest.mark.parametrize(
    ("fitted", "version"),
    [
        (Ms5837Model.BA30, 0b0011010),  # an MS5837-30BA26
        (Ms5837Model.BA02, 0b0010101),  # an MS5837-02BA21
        (Ms5837Model.BA30, 0),  # an older MS5837-30BA01: 0, as an MS5837-02BA01
        (Ms5837Model.BA02, 0),
        (Ms5837Model.BA30, 0b1111111),  # a version no datasheet lists
    ],
)
def test_a_model_its_prom_names_or_cannot_tell_starts(fitted: Ms5837Model, version: int) -> None:
    _, d1, d2 = MS5837_EXAMPLES[fitted]
    fake = FakeMs5837(_prom_with_version(fitted, version), d1, d2, fitted)
    _, sensor, _bus = _sensor(fitted, fake)
    sensor.start()
    assert product_version(sensor.prom[0]) == version


def test_the_crc_ignores_its_own_nibble_and_sees_every_word() -> None:
    prom = ms5837_prom(MS5837_EXAMPLES[Ms5837Model.BA02][0])
    assert crc4(prom) == crc4([prom[0] & 0x0FFF, *prom[1:]])
    values = {
        crc4([prom[0], *prom[1:index], prom[index] ^ 1, *prom[index + 1 :]])
        for index in range(1, 7)
    }
    assert crc4(prom) not in values


def test_conversions_alternate_without_waiting() -> None:
    fake, sensor, bus = _sensor(Ms5837Model.BA02)
    sensor.start()
    assert _poll_at(sensor, bus, 0.0) is None  # D1 started
    before = len(bus.transactions)
    assert _poll_at(sensor, bus, 0.005) is None  # 5 ms: the 9 ms conversion is under way, no I/O
    assert len(bus.transactions) == before
    assert _poll_at(sensor, bus, 0.010) is None  # D1 read, D2 started
    reading = _poll_at(sensor, bus, 0.020)  # D2 read: a reading; D1 started
    assert reading is not None
    assert reading.pressure_mbar == pytest.approx(1100.02)
    assert fake.conversions == [0x48, 0x58, 0x48]  # OSR 4096: D1 0x48, D2 0x58


def test_the_read_waits_a_whole_conversion_after_the_convert_commands_write() -> None:
    # A slow bus (a device stretching the clock, a long transfer before): each transaction takes
    # 4 ms. Counted from the period's start, the conversion would be read 5 ms after its command
    # went, mid-conversion: the datasheet's 0, which spoils it.
    _fake, sensor, bus = _sensor(Ms5837Model.BA02, transaction_s=0.004)
    sensor.start()
    first = len(bus.transactions)
    readings = [_poll_at(sensor, bus, period * 0.001) for period in range(1, 200)]
    assert sum(reading is not None for reading in readings) >= 3
    converted_s: float | None = None  # when the last convert command's write ended
    for transaction, started_s in zip(bus.transactions[first:], bus.started_s[first:], strict=True):
        if transaction.written[0] in (0x48, 0x58):  # convert D1, D2 at OSR 4096
            converted_s = started_s + bus.transaction_s
        elif transaction.written == b"\x00":  # the ADC read
            assert converted_s is not None
            assert started_s >= converted_s + sensor.conversion_s, (started_s, converted_s)


def test_a_conversion_read_as_zero_sends_the_reset_and_restarts_the_cycle_after_it() -> None:
    # A lost conversion, most likely a chip reset by a supply dip: the datasheet has the reset
    # command sent after a power-on (it loads the PROM into the chip's registers), and it takes
    # 2.8 ms, in which nothing else is sent.
    fake, sensor, bus = _sensor(Ms5837Model.BA02)
    sensor.start()
    assert fake.resets == 1
    _poll_at(sensor, bus, 0.0)
    fake._converted = 0  # the conversion was lost (the datasheet's answer: 0)
    with pytest.raises(SensorError, match=r"0x76: conversion read as 0"):
        _poll_at(sensor, bus, 0.010)
    assert fake.resets == 2
    assert bus.transactions[-1].written == b"\x1e"
    sent = len(bus.transactions)
    assert _poll_at(sensor, bus, 0.0127) is None  # 2.7 ms after the reset: nothing sent
    assert len(bus.transactions) == sent
    assert _poll_at(sensor, bus, 0.0131) is None  # D1 again
    assert bus.transactions[-1].written == b"\x48"
    assert _poll_at(sensor, bus, 0.0231) is None
    assert _poll_at(sensor, bus, 0.0331) == (1100.02, 20.00)


def test_a_temperature_outside_the_datasheets_range_is_a_corrupt_conversion() -> None:
    # The 30BA example's D2 with its bit 23 set, as a bit flipped on a noisy bus would:
    # dT = 15204022 − 26646·2⁸ = 8382646, TEMP = 2000 + 8382646·26146 / 2²³ = 28127
    # (281.27 °C, outside TEMP's −4000…8500), and OFF = 36352·2¹⁶ + 22354·dT / 2⁷,
    # SENS = 34982·2¹⁵ + 20328·dT / 2⁸, P = (D1·SENS / 2²¹ − OFF) / 2¹³ = 53407 (5340.7 mbar):
    # 44 m of water, a plausible depth. Second order (TEMP ≥ 2000): Ti = 2·dT² / 2³⁷ = 1022,
    # so the reading is 271.05 °C.
    coefficients, d1, d2 = MS5837_EXAMPLES[Ms5837Model.BA30]
    corrupt_d2 = d2 | 1 << 23
    assert corrupt_d2 == 15204022
    assert compensate(Ms5837Model.BA30, [0, *coefficients], d1, corrupt_d2, second_order=False) == (
        5340.7,
        281.27,
    )
    fake, sensor, bus = _sensor(Ms5837Model.BA30)
    sensor.start()
    fake.d2 = corrupt_d2
    _poll_at(sensor, bus, 0.0)
    _poll_at(sensor, bus, 0.010)
    with pytest.raises(SensorError, match=r"0x76: it reads 271\.05 °C, outside the -40–85 °C"):
        _poll_at(sensor, bus, 0.020)
    fake.d2 = d2  # the next pair is whole: read as ever
    assert _poll_at(sensor, bus, 0.030) is None
    assert _poll_at(sensor, bus, 0.040) == (3999.8, 19.81)


def test_a_reset_that_fails_after_a_lost_conversion_starts_the_cycle_over() -> None:
    fake, sensor, bus = _sensor(Ms5837Model.BA02)
    sensor.start()
    _poll_at(sensor, bus, 0.0)
    fake._converted = 0
    real_write = bus.write

    def reset_fails(address: int, data: bytes) -> None:
        if data == b"\x1e":
            raise OSError(121, "no acknowledge")
        real_write(address, data)

    bus.write = reset_fails  # type: ignore[method-assign]
    with pytest.raises(SensorError, match="read as 0"):
        _poll_at(sensor, bus, 0.010)
    bus.write = real_write  # type: ignore[method-assign]
    assert _poll_at(sensor, bus, 0.011) is None  # D1 at once: no reset to wait for
    assert bus.transactions[-1].written == b"\x48"
    assert _poll_at(sensor, bus, 0.021) is None
    assert _poll_at(sensor, bus, 0.031) == (1100.02, 20.00)


def test_an_i2c_failure_surfaces_as_oserror() -> None:
    _fake, sensor, bus = _sensor(Ms5837Model.BA02)
    sensor.start()
    _poll_at(sensor, bus, 0.0)
    bus.fail(0x76, 1)
    with pytest.raises(OSError, match="no acknowledge"):
        _poll_at(sensor, bus, 0.010)


#: The sensor's steps: 0.1 mbar (30BA) or 0.01 mbar (02BA), and 0.01 °C.
_RESOLUTION_MBAR = {Ms5837Model.BA30: 0.1, Ms5837Model.BA02: 0.01}


@pytest.mark.parametrize("model", list(Ms5837Model))
@pytest.mark.parametrize(
    ("pressure_mbar", "temperature_c"),
    [
        (1013.25, 20.0),  # the surface
        (1257.68, 4.0),  # 2.5 m of fresh water, cold: the second-order terms
        (1100.0, 25.0),  # warm: the 30BA's high-temperature second order
        (800.0, -20.0),  # the 30BA's very-low-temperature branch
        (1999.99, 60.0),
    ],
)
def test_a_reading_set_on_the_fake_is_what_the_compensation_gives_back(
    model: Ms5837Model, pressure_mbar: float, temperature_c: float
) -> None:
    fake = FakeMs5837.reading(model, pressure_mbar, temperature_c)
    reading = compensate(model, fake.prom, fake.d1, fake.d2)
    assert abs(reading.pressure_mbar - pressure_mbar) <= _RESOLUTION_MBAR[model] / 2 + 1e-9
    assert abs(reading.temperature_c - temperature_c) <= 0.005 + 1e-9


def test_the_fake_reads_the_datasheet_example_until_a_reading_is_set() -> None:
    fake, sensor, bus = _sensor(Ms5837Model.BA30)
    sensor.start()
    readings = [_poll_at(sensor, bus, period * 0.010) for period in range(3)]
    assert readings[2] == (3999.8, 19.81)  # the datasheet's example, second order: 19.81 °C
    fake.set_reading(1013.25, 15.0)
    readings = [_poll_at(sensor, bus, period * 0.010) for period in range(3, 7)]
    assert readings[-1] is not None
    assert readings[-1].pressure_mbar == pytest.approx(1013.25, abs=0.05)
    assert readings[-1].temperature_c == pytest.approx(15.0, abs=0.005)


def test_a_reading_out_of_the_sensors_reach_is_refused_naming_it() -> None:
    fake = FakeMs5837.example(Ms5837Model.BA02)
    with pytest.raises(ValueError, match=r"MS5837-02BA: 40000 mbar at 20 °C is out of the"):
        fake.set_reading(40_000.0)
    with pytest.raises(ValueError, match="must be finite"):
        fake.set_reading(float("nan"))
    assert (fake.d1, fake.d2) == MS5837_EXAMPLES[Ms5837Model.BA02][1:]
