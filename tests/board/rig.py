"""Shared pieces of the board tests: the example rov.toml on fake buses, and the pulses an
oscilloscope would see, rebuilt from the recorded I²C transactions."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from rovlink.board.pi.config import PiConfig, load_pi_config
from rovlink.board.pi.fake_bus import FakePca9685, Transaction
from rovlink.controller.config import read_toml

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "rov.toml"
PCA_ADDRESS = 0x40
#: The example's channels, in layout order: front_left … vertical_right, then the claw.
THRUSTER_CHANNELS = (0, 1, 2, 3, 4, 5)
CLAW_CHANNEL = 8
#: One PCA9685 count at 50 Hz (prescale 121): 4096 counts in 19988 µs.
COUNT_US = 4096 * 122 / 25e6 * 1e6 / 4096
NEUTRAL_US = 1500.0
CONDITION_TIMEOUT_S = 10.0


def example_config(**tables: dict[str, Any]) -> PiConfig:
    """The example rov.toml on the fake bus, with ``tables`` merged over its tables."""
    data = read_toml(EXAMPLE)
    data["i2c"]["backend"] = "fake"
    for name, values in tables.items():
        data.setdefault(name, {}).update(values)
    from rovlink.board.pi.config import pi_config_from_mapping

    return pi_config_from_mapping(data, "rov.toml")


#: The second PWM board of :func:`two_pwm_boards_data`.
SECOND_PCA_ADDRESS = 0x41


def two_pwm_boards_data() -> dict[str, Any]:
    """The example rov.toml (fake bus, no IMU: its driver's reset takes a second) with a
    second PCA9685 at 0x41 on the same bus, which drives the vertical thrusters on its
    channels 0 and 1 and the claw on its channel 15."""
    data = read_toml(EXAMPLE)
    data["i2c"]["backend"] = "fake"
    data["imu"]["sensor"] = "none"
    data["pca9685"] = [data["pca9685"], {"address": SECOND_PCA_ADDRESS}]
    data["esc"]["vertical_left"].update(pca9685=SECOND_PCA_ADDRESS, channel=0)
    data["esc"]["vertical_right"].update(pca9685=SECOND_PCA_ADDRESS, channel=1)
    data["claw"].update(pca9685=SECOND_PCA_ADDRESS, channel=15)
    return data


def fake_toml(tmp_path: Path, log: Path, *, model: str = "02ba", watchdog_s: float = 2.0) -> Path:
    """A copy of the example rov.toml for a process on the fake bus, logging to ``log``."""
    text = EXAMPLE.read_text(encoding="utf-8")
    text = text.replace('backend = "smbus2"', f'backend = "fake"\nfake_log = "{log}"')
    text = text.replace('model = "30ba"', f'model = "{model}"')
    text = text.replace("watchdog_s = 2.0", f"watchdog_s = {watchdog_s}")
    path = tmp_path / "rov.toml"
    path.write_text(text, encoding="utf-8")
    assert load_pi_config(path).i2c.fake_log == str(log)
    return path


def replay(transactions: Iterable[Transaction], address: int = PCA_ADDRESS) -> FakePca9685:
    """A fresh PCA9685 given every successful write to ``address``: the chip's state."""
    chip = FakePca9685()
    for transaction in transactions:
        if transaction.address == address and not transaction.failed and transaction.written:
            chip.write(transaction.written)
    return chip


def pulses(
    transactions: Iterable[Transaction],
    channels: Sequence[int] = THRUSTER_CHANNELS,
    address: int = PCA_ADDRESS,
) -> list[float | None]:
    """The pulse on each of ``channels`` of the PCA9685 at ``address``, µs, after
    ``transactions``."""
    chip = replay(transactions, address)
    return [chip.pulse_us(channel) for channel in channels]


def is_neutral(values: Sequence[float | None]) -> bool:
    """Every pulse at neutral, within half a count."""
    return all(value is not None and abs(value - NEUTRAL_US) <= COUNT_US / 2 for value in values)


def read_log(path: Path) -> list[Transaction]:
    """The transactions a process wrote to its fake_log."""
    if not path.exists():
        return []
    lines = path.read_text(encoding="utf-8").splitlines()
    return [Transaction.from_json(line) for line in lines if line.endswith("}")]


def wait_until(condition: Callable[[], bool], timeout_s: float = CONDITION_TIMEOUT_S) -> bool:
    """Poll ``condition`` until it holds or the timeout passes; whether it held."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


def with_controller(config: PiConfig, **changes: Any) -> PiConfig:
    """``config`` with controller settings changed."""
    return dataclasses.replace(config, controller=dataclasses.replace(config.controller, **changes))
