"""The PCA9685 driver against a fake chip that records every transaction."""

from __future__ import annotations

import pytest

from rovlink.board.pi.fake_bus import FakeI2cBus, FakePca9685
from rovlink.board.pi.outputs import EscChannel, EscThrusters, pulse_for_duty
from rovlink.board.pi.pca9685 import Pca9685, prescale_for
from tests.board.rig import COUNT_US


def _chip() -> tuple[FakeI2cBus, FakePca9685, Pca9685]:
    fake = FakePca9685()
    bus = FakeI2cBus({0x40: fake})
    return bus, fake, Pca9685(bus)


def test_prescale_follows_the_datasheet_formula() -> None:
    # round(25 MHz / (4096 × 50 Hz)) − 1 = round(122.07) − 1
    assert prescale_for(50.0) == 121
    # The datasheet's power-on value 0x1E is its 200 Hz.
    assert prescale_for(200.0) == 0x1E
    # A 26.5 MHz chip (trimmed) needs a larger prescale for the same 50 Hz.
    assert prescale_for(50.0, 26_500_000.0) == 128


@pytest.mark.parametrize("frequency_hz", [10.0, 2000.0])
def test_a_frequency_out_of_reach_is_refused(frequency_hz: float) -> None:
    with pytest.raises(ValueError, match="PWM frequency must be 24–1526 Hz"):
        prescale_for(frequency_hz)


def test_start_writes_prescale_and_neutral_before_the_oscillator_runs() -> None:
    bus, fake, pca = _chip()
    pca.start(50.0, {0: 1500.0, 5: 1500.0})
    assert fake.prescale == 121
    assert not fake.sleeping
    # Replay the start transaction by transaction: at the moment the oscillator starts, every
    # configured output already holds neutral and every other output is off.
    chip = FakePca9685()
    for transaction in bus.transactions:
        was_sleeping = chip.sleeping
        chip.write(transaction.written)
        if was_sleeping and not chip.sleeping:
            assert chip.prescale == 121
            for channel in (0, 5):
                value = chip.pulse_us(channel)
                assert value is not None
                assert abs(value - 1500.0) <= COUNT_US / 2
            assert all(chip.pulse_us(channel) is None for channel in (1, 2, 3, 4, 6, 15))
            break
    else:
        pytest.fail("the oscillator never started")


def test_consecutive_channels_go_out_in_one_write_and_unchanged_ones_not_at_all() -> None:
    bus, fake, pca = _chip()
    pca.start(50.0, {})
    before = len(bus.transactions)
    pca.set_pulses_us({0: 1600.0, 1: 1600.0, 2: 1600.0, 7: 1400.0})
    writes = bus.transactions[before:]
    assert [w.written[0] for w in writes] == [0x06, 0x06 + 4 * 7]
    assert len(writes[0].written) == 1 + 3 * 4
    for channel in (0, 1, 2):
        value = fake.pulse_us(channel)
        assert value is not None
        assert abs(value - 1600.0) <= COUNT_US / 2
    before = len(bus.transactions)
    pca.set_pulses_us({0: 1600.0, 7: 1400.0})
    assert len(bus.transactions) == before


def test_a_pulse_longer_than_the_period_is_refused() -> None:
    _, _, pca = _chip()
    pca.start(200.0, {})
    with pytest.raises(ValueError, match="does not fit"):
        pca.set_pulses_us({0: 5500.0})


def test_esc_pulses_span_the_range_and_reverse() -> None:
    esc = EscChannel(0, min_us=1100.0, neutral_us=1500.0, max_us=1900.0)
    assert pulse_for_duty(esc, 0) == 1500.0
    assert pulse_for_duty(esc, 255) == 1900.0
    assert pulse_for_duty(esc, -255) == 1100.0
    assert pulse_for_duty(esc, 1000) == 1900.0  # clamped
    # An asymmetric range: each side scales to its own end.
    lopsided = EscChannel(0, min_us=1000.0, neutral_us=1500.0, max_us=1800.0)
    assert pulse_for_duty(lopsided, -255) == 1000.0
    assert pulse_for_duty(lopsided, 255) == 1800.0
    reverse = EscChannel(0, reversed=True)
    assert pulse_for_duty(reverse, 255) == 1100.0


def test_neutral_is_written_even_when_the_driver_believes_it_is_there() -> None:
    bus, fake, pca = _chip()
    thrusters = EscThrusters(pca, [EscChannel(0), EscChannel(1)])
    pca.start(50.0, thrusters.neutral_pulses_us())
    # Someone else (a restarted chip, a glitch) changed the outputs behind the driver's back.
    fake.write(bytes([0x06, 0, 0, 0x60, 0x01]))
    before = len(bus.transactions)
    thrusters.neutral()
    assert len(bus.transactions) > before
    value = fake.pulse_us(0)
    assert value is not None
    assert abs(value - 1500.0) <= COUNT_US / 2
