"""A leak probe whose GPIO cannot be opened: the board refuses to start with one line naming the
probe and its pin, outputs at neutral, rather than a traceback from gpiozero."""

from __future__ import annotations

import importlib.util

import pytest

from rovlink.board.board import BoardStartError
from rovlink.board.pi.board import fake_bus_for, open_pi_board
from tests.board.rig import example_config, is_neutral, pulses


def _pin_factory_from(monkeypatch: pytest.MonkeyPatch, name: str) -> None:
    """gpiozero choosing its pin factory afresh, as GPIOZERO_PIN_FACTORY says."""
    from gpiozero import Device

    monkeypatch.setattr(Device, "pin_factory", None)
    monkeypatch.setenv("GPIOZERO_PIN_FACTORY", name)


def _start_failure_with_the_pin_factory_of_the_system() -> str:
    """Why the board did not start, gpiozero picking its own pin factory (the real backend's
    way; the bus is a fake one); the thrusters were left at neutral."""
    config = example_config(i2c={"backend": "smbus2"}, imu={"sensor": "none"})
    bus = fake_bus_for(config)
    with pytest.raises(BoardStartError) as caught:
        open_pi_board(config, bus=bus)
    assert is_neutral(pulses(bus.snapshot()))
    message = str(caught.value)
    assert message.startswith("leak probe on GPIO 27: ")
    return message


def test_no_pin_library_for_gpiozero_is_named_with_the_remedy(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # What gpiozero raises when none of its pin libraries loads (a Pi 5's venv without lgpio):
    # BadPinFactory, an ImportError that is not a ModuleNotFoundError.
    _pin_factory_from(monkeypatch, "no-such-factory")
    message = _start_failure_with_the_pin_factory_of_the_system()
    assert "no-such-factory" in message
    assert "lgpio" in message
    assert "--system-site-packages" in message


#: A directory no file can be made in, even by root: as ``/`` is to a service's user.
_UNWRITABLE = "/proc"


def test_a_working_directory_lgpio_cannot_write_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    # A service runs in / unless its unit says otherwise, and lgpio makes its notification
    # pipes in the working directory as it loads: it failed to, gpiozero found no other pin
    # library, and the message sent the user to install the lgpio they had.
    _pin_factory_from(monkeypatch, "no-such-factory")
    monkeypatch.chdir(_UNWRITABLE)
    message = _start_failure_with_the_pin_factory_of_the_system()
    assert f"the working directory {_UNWRITABLE} cannot be written" in message
    assert "WorkingDirectory=" in message


def test_lgpio_failing_to_make_its_pipe_names_the_working_directory(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # What lgpio raises as it loads (GPIOZERO_PIN_FACTORY=lgpio) in a directory it cannot
    # write: the start-up error read "No such file or directory", naming no file.
    import gpiozero

    def lgpio_loading(*args: object, **kwargs: object) -> None:
        raise FileNotFoundError(2, "No such file or directory", ".lgd-nfy-3")

    monkeypatch.setattr(gpiozero, "DigitalInputDevice", lgpio_loading)
    monkeypatch.chdir(_UNWRITABLE)
    message = _start_failure_with_the_pin_factory_of_the_system()
    assert ".lgd-nfy-3" in message
    assert f"the working directory {_UNWRITABLE} cannot be written" in message


@pytest.mark.skipif(importlib.util.find_spec("pigpio") is not None, reason="pigpio is installed")
def test_a_missing_pin_library_is_not_blamed_on_the_pi_extra(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The pi extra does not bring a pin library: the system's python3-lgpio does.
    _pin_factory_from(monkeypatch, "pigpio")
    message = _start_failure_with_the_pin_factory_of_the_system()
    assert "pigpio" in message
    assert "--system-site-packages" in message
    assert "rovlink[pi]" not in message


def test_a_pin_in_use_is_named() -> None:
    from gpiozero import DigitalInputDevice
    from gpiozero.pins.mock import MockFactory

    factory = MockFactory()
    other = DigitalInputDevice(27, pin_factory=factory)  # another program's, say
    try:
        config = example_config(imu={"sensor": "none"})
        bus = fake_bus_for(config)
        with pytest.raises(BoardStartError, match=r"^leak probe on GPIO 27: .*in use"):
            open_pi_board(config, bus=bus, pin_factory=factory)
        assert is_neutral(pulses(bus.snapshot()))
    finally:
        other.close()
        factory.close()


def test_a_pin_with_a_fixed_pull_is_named() -> None:
    # GPIO 2 and 3 (I²C bus 1) have fixed pull-ups on a Pi: a pull-down cannot be set on
    # them. (rov.toml refuses them while the board uses bus 1: here its devices are on bus 3.)
    from gpiozero.pins.mock import MockFactory

    factory = MockFactory()
    try:
        config = example_config(imu={"sensor": "none"}, leak={"pin": 2}, i2c={"bus": 3})
        bus = fake_bus_for(config)
        with pytest.raises(BoardStartError, match=r"^leak probe on GPIO 2: .*fixed pull"):
            open_pi_board(config, bus=bus, pin_factory=factory)
        assert is_neutral(pulses(bus.snapshot()))
    finally:
        factory.close()
