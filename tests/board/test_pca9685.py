"""The PCA9685 driver against a fake chip that records every transaction."""

from __future__ import annotations

import pytest

from rovlink.board.pi.fake_bus import FakeI2cBus, FakePca9685
from rovlink.board.pi.outputs import EscChannel, EscThrusters, pulse_for_duty
from rovlink.board.pi.pca9685 import Pca9685, prescale_for
from rovlink.board.pi.pca9685_watch import Pca9685ResetWatch
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
    thrusters = EscThrusters([pca], [(pca, EscChannel(0)), (pca, EscChannel(1))])
    pca.start(50.0, thrusters.neutral_pulses_us()[pca])
    # Someone else (a restarted chip, a glitch) changed the outputs behind the driver's back.
    fake.write(bytes([0x06, 0, 0, 0x60, 0x01]))
    before = len(bus.transactions)
    thrusters.neutral()
    assert len(bus.transactions) > before
    value = fake.pulse_us(0)
    assert value is not None
    assert abs(value - 1500.0) <= COUNT_US / 2


def test_a_chip_reset_by_a_supply_dip_makes_no_pulses_and_acknowledges_every_write() -> None:
    """What the read-back is for: after a reset the writes still succeed, and nothing runs."""
    _bus, fake, pca = _chip()
    pca.start(50.0, {0: 1500.0, 1: 1500.0})
    fake.power_on_reset()
    pca.forget_written()
    pca.set_pulses_us({0: 1700.0, 1: 1700.0})  # no error
    assert fake.sleeping
    assert fake.pulse_us(0) is None
    assert fake.pulse_us(1) is None


def test_reading_back_finds_a_reset_and_says_what_differs() -> None:
    bus, fake, pca = _chip()
    pca.start(50.0, {0: 1500.0})
    before = len(bus.transactions)
    assert pca.reset_found() is None
    reads = bus.transactions[before:]
    # Two one-byte register reads, MODE1 and PRE_SCALE, and nothing written to the chip.
    assert [(t.written, len(t.read)) for t in reads] == [(b"\x00", 1), (b"\xfe", 1)]
    fake.power_on_reset()
    found = pca.reset_found()
    assert found == (
        "MODE1 reads 0x11, not 0x20, PRE_SCALE reads 0x1e, not 0x79 (asleep: no pulses)"
    )


def test_a_chip_at_200_hz_is_found_reset_by_its_mode_alone() -> None:
    # 200 Hz is the power-on prescale (0x1E): only MODE1 tells a reset chip from a started one.
    _bus, fake, pca = _chip()
    pca.start(200.0, {0: 1500.0})
    assert pca.reset_found() is None
    fake.power_on_reset()
    assert pca.reset_found() == "MODE1 reads 0x11, not 0x20 (asleep: no pulses)"


def _watch(interval_s: float = 0.1) -> tuple[FakeI2cBus, FakePca9685, Pca9685, Pca9685ResetWatch]:
    bus, fake, pca = _chip()
    thrusters = EscThrusters([pca], [(pca, EscChannel(0)), (pca, EscChannel(1, reversed=True))])
    pca.start(50.0, thrusters.neutral_pulses_us()[pca])
    return (
        bus,
        fake,
        pca,
        Pca9685ResetWatch(pca, lambda: thrusters.neutral_pulses_us()[pca], interval_s),
    )


def _period(watch: Pca9685ResetWatch, now_s: float) -> str | None:
    """A control period at ``now_s``, as the board loop runs a check: only when it is due."""
    return watch.check(now_s) if watch.is_due(now_s) else None


def test_the_watch_reads_back_at_most_once_an_interval() -> None:
    bus, _fake, _pca, watch = _watch(interval_s=0.1)
    before = len(bus.transactions)
    # One second of a 100 Hz control loop: ten checks of two reads, not a hundred.
    assert all(_period(watch, period * 0.01) is None for period in range(100))
    reads = bus.transactions[before:]
    assert len(reads) == 2 * 10
    assert all(len(t.read) == 1 and t.written in (b"\x00", b"\xfe") for t in reads)


def test_a_reset_is_reported_counted_and_the_chip_started_again_at_neutral() -> None:
    _bus, fake, pca, watch = _watch()
    assert _period(watch, 0.0) is None
    escs = [(pca, EscChannel(0)), (pca, EscChannel(1, reversed=True))]
    EscThrusters([pca], escs).set_duties([200, 200])
    fake.power_on_reset()
    assert _period(watch, 0.05) is None  # not due yet: the ESCs are without pulses until 0.1 s
    fault = _period(watch, 0.1)
    assert fault is not None
    assert fault.startswith("PWM board PCA9685 at 0x40 was reset (MODE1 reads 0x11")
    assert fault.endswith("started again, outputs at neutral")
    assert watch.resets == 1
    assert fake.power_on_resets == 1
    assert not fake.sleeping
    assert fake.prescale == 121
    for channel in (0, 1):  # neutral, not the thrust the chip made before its reset
        value = fake.pulse_us(channel)
        assert value is not None
        assert abs(value - 1500.0) <= COUNT_US / 2
    assert fake.pulse_us(2) is None
    assert _period(watch, 0.2) is None
    assert watch.resets == 1


def test_a_read_back_the_chip_does_not_answer_is_an_oserror_and_checked_again() -> None:
    bus, fake, _pca, watch = _watch()
    bus.fail(0x40, 1)
    with pytest.raises(OSError, match="no acknowledge"):
        _period(watch, 0.0)
    fake.power_on_reset()
    assert _period(watch, 0.1) is not None
    assert watch.resets == 1


def test_a_restart_that_fails_is_tried_again_and_the_reset_counted_once() -> None:
    bus, fake, _pca, watch = _watch()
    fake.power_on_reset()
    # The read-back succeeds (two reads), then the first write of the restart fails.
    real_write = bus.write
    failures = [1]

    def failing_write(address: int, data: bytes) -> None:
        if failures[0]:
            failures[0] -= 1
            raise OSError(121, "Remote I/O error")
        real_write(address, data)

    bus.write = failing_write  # type: ignore[method-assign]
    fault = _period(watch, 0.0)
    assert fault is not None
    assert "starting it again failed ([Errno 121] Remote I/O error), tried again in 0.1 s" in fault
    assert fake.sleeping
    fault = _period(watch, 0.1)
    assert fault is not None
    assert fault.endswith("started again, outputs at neutral")
    assert not fake.sleeping
    assert watch.resets == 1


@pytest.mark.parametrize("interval_s", [0.0, -1.0, float("nan")])
def test_a_watch_interval_that_is_not_positive_is_refused(interval_s: float) -> None:
    _bus, _fake, pca = _chip()
    with pytest.raises(ValueError, match="interval_s must be > 0"):
        Pca9685ResetWatch(pca, dict, interval_s)


def test_taking_over_a_running_chip_sets_only_the_pulses_given() -> None:
    # A controller killed while driving: channel 0 a thruster at full ahead, 8 a servo claw.
    bus, fake, controller = _chip()
    controller.start(50.0, {0: 1500.0, 8: 1500.0})
    controller.set_pulses_us({0: 1900.0, 8: 1300.0})
    before = len(bus.transactions)
    after_death = Pca9685(bus)
    assert after_death.take_over(50.0, {0: 1500.0}, {0: 1500.0, 8: 1500.0}) is False
    assert abs((fake.pulse_us(0) or 0) - 1500.0) <= COUNT_US
    assert abs((fake.pulse_us(8) or 0) - 1300.0) <= COUNT_US  # the servo holds its place
    written = [t.written for t in bus.transactions[before:] if len(t.written) > 1]
    assert written == [bytes([0x06, 0, 0, 307 & 0xFF, 307 >> 8])]  # no sleep, no restart


def test_taking_over_a_chip_that_was_reset_starts_it() -> None:
    _bus, fake, controller = _chip()
    controller.start(50.0, {0: 1500.0, 8: 1500.0})
    controller.set_pulses_us({0: 1900.0})
    fake.power_on_reset()
    after_death = Pca9685(_bus)
    assert after_death.take_over(50.0, {0: 1500.0}, {0: 1500.0, 8: 1600.0}) is True
    assert not fake.sleeping
    assert fake.prescale == 121
    assert abs((fake.pulse_us(0) or 0) - 1500.0) <= COUNT_US
    assert abs((fake.pulse_us(8) or 0) - 1600.0) <= COUNT_US


def test_taking_over_a_chip_that_does_not_answer_tries_to_start_it() -> None:
    bus, _fake, _controller = _chip()
    bus.fail(0x40, 1)  # the read-back; the start that follows is answered
    after_death = Pca9685(bus)
    assert after_death.take_over(50.0, {0: 1500.0}, {0: 1500.0}) is True
    bus.fail(0x40, 100)
    with pytest.raises(OSError, match="no acknowledge from 0x40"):
        Pca9685(bus).take_over(50.0, {0: 1500.0}, {0: 1500.0})


def _two_chips() -> tuple[FakeI2cBus, EscThrusters, list[FakePca9685]]:
    """Two PCA9685 on one bus, two ESCs on each (both on channel 0 and 1)."""
    fakes = [FakePca9685(), FakePca9685()]
    bus = FakeI2cBus({0x40: fakes[0], 0x41: fakes[1]})
    first, second = Pca9685(bus, 0x40), Pca9685(bus, 0x41)
    escs = [(pca, EscChannel(channel)) for pca in (first, second) for channel in (0, 1)]
    thrusters = EscThrusters([first, second], escs)
    for pca, pulses in thrusters.neutral_pulses_us().items():
        pca.start(50.0, pulses)
    return bus, thrusters, fakes


def test_thrusters_on_two_chips_are_set_with_one_write_to_each() -> None:
    bus, thrusters, fakes = _two_chips()
    before = len(bus.transactions)
    thrusters.set_duties([255, 255, -255, -255])
    writes = bus.transactions[before:]
    assert [t.address for t in writes] == [0x40, 0x41]
    assert [fakes[0].pulse_us(0), fakes[1].pulse_us(1)] == pytest.approx([1900, 1100], abs=COUNT_US)


@pytest.mark.parametrize("method", ["set_duties", "neutral"])
def test_a_chip_that_does_not_answer_leaves_the_other_written(method: str) -> None:
    bus, thrusters, fakes = _two_chips()
    thrusters.set_duties([255, 255, 255, 255])
    bus.fail(0x40, 10)  # the first chip is gone, the second must still stop
    stop = thrusters.neutral if method == "neutral" else lambda: thrusters.set_duties([0] * 4)
    with pytest.raises(OSError, match="no acknowledge from 0x40"):
        stop()
    assert [fakes[1].pulse_us(0), fakes[1].pulse_us(1)] == pytest.approx([1500] * 2, abs=COUNT_US)
    assert fakes[0].pulse_us(0) == pytest.approx(1900, abs=COUNT_US)  # (as it was left)
