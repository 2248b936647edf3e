"""rov.toml: the example loads, and a wrong file is refused naming the key and the reason."""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import Any

import pytest

from rovlink.board.pi.config import (
    ClawKind,
    PressureKind,
    load_pi_config,
    load_pi_outputs_config,
    pi_config_from_mapping,
    pi_config_reference,
)
from rovlink.board.pi.ms5837 import Ms5837Model
from rovlink.controller import ConfigError, LeakAction
from rovlink.controller.config import read_toml
from tests.board.rig import EXAMPLE, two_pwm_boards_data


def test_the_documented_example_loads() -> None:
    config = load_pi_config(EXAMPLE)
    assert [esc.channel for esc in config.escs] == [0, 1, 2, 3, 4, 5]
    assert [esc.reversed for esc in config.escs] == [False, True, False, True, False, True]
    assert config.claw.kind is ClawKind.MOTOR
    assert config.pressure.sensor is PressureKind.MS5837
    assert config.pressure.ms5837.model is Ms5837Model.BA30
    assert config.controller.leak_action is LeakAction.STOP
    assert config.leak.pin == 27
    assert [pwm.address for pwm in config.pwm_boards] == [0x40]
    assert config.pwm_boards[0].check_interval_s == 0.1


def test_the_reference_names_every_board_table() -> None:
    reference = pi_config_reference()
    for table in ("[i2c]", "[pca9685]", "[esc.<thruster name>]", "[pressure.ms5837]", "[leak]"):
        assert table in reference


def _load(**changes: object) -> None:
    data = read_toml(EXAMPLE)
    for dotted, value in changes.items():
        *path, key = dotted.split("__")
        table = data
        for name in path:
            table = table.setdefault(name, {})
        if value is None:
            del table[key]
        else:
            table[key] = value
    pi_config_from_mapping(data, "rov.toml")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"esc__rear_left": None}, "[esc]: thruster 'rear_left' has no ESC output"),
        ({"esc__aft": {"channel": 9}}, "[esc.aft]: no thruster of that name in the layout"),
        ({"esc__rear_left__channel": None}, "[esc.rear_left]: channel is required"),
        (
            {"esc__rear_left__channel": 0},
            "[esc.rear_left] channel: 0 is already used by [esc.front_left]",
        ),
        ({"claw__channel": 5}, "[claw] channel: 5 is already used by [esc.vertical_right]"),
        ({"esc__front_left__channel": 16}, "[esc.front_left]: channel must be 0–15, got 16"),
        (
            {"esc__front_left__min_us": 1600.0},
            "[esc.front_left]: pulses must rise min_us < neutral_us < max_us",
        ),
        (
            {"esc__front_left__max_us": "1900"},
            "[esc.front_left] max_us must be float, got str '1900'",
        ),
        (
            {"pca9685__frequency_hz": 5.0},
            "[pca9685]: frequency_hz: PWM frequency must be 24–1526 Hz",
        ),
        (
            {"pca9685__frequency_hz": 600.0},
            "[pca9685] frequency_hz: a 1900 µs pulse does not fit in the 1638 µs period",
        ),
        ({"pca9685__adress": 0x41}, "[pca9685]: unknown key 'adress'"),
        (
            {"pca9685__check_interval_s": 0.001},
            "[pca9685]: check_interval_s must be 0 (never) or 0.01–60, got 0.001",
        ),
        (
            {"pca9685__address": 0x80},
            "[pca9685]: address must be an I²C address 0x03–0x77, got 128",
        ),
        (
            {"pressure__sensor": "bmp280"},
            "[pressure] sensor must be one of ms5837, ads1115, got 'bmp280'",
        ),
        ({"pressure__ms5837__model": "05ba"}, "[pressure.ms5837] model must be one of 30ba, 02ba"),
        (
            {"pressure__ms5837__oversampling": 300},
            "[pressure.ms5837]: oversampling must be one of 256",
        ),
        (
            {"pressure__ads1115__full_scale_v": 4.096, "pressure__ads1115__max_volts": 4.5},
            "[pressure.ads1115]: max_volts must be at most full_scale_v (4.096 V), got 4.5",
        ),
        ({"imu__placement": "P9"}, "[imu]: placement must be one of P0, P1"),
        (
            {"leak__pull": "up"},
            "[leak]: pull = 'up' makes the pin rest high: it cannot be active high",
        ),
        ({"i2c__fake_log": "x.jsonl"}, '[i2c]: fake_log is for backend = "fake" only'),
        ({"board__stale_after_s": -0.5}, "[board]: stale_after_s must be 0–10 s, got -0.5"),
        ({"controller__watchdog_s": -1.0}, "[controller]: watchdog_s must be ≥ 0"),
        (
            {"depth__k": 0},
            "[depth]: k must be in 1–10000 on a Pi board (a raw count is k / 100 cm of water), "
            "got 0",
        ),
        # Two devices at one address on one bus: the writes of one would go to the other
        # (an ADS1115's config word lands in a PCA9685's MODE2, making its outputs open-drain).
        # TOML reads 40 as forty: the BNO055's 0x28, not the PCA9685's 0x40.
        (
            {"pca9685__address": 0x76},
            "rov.toml [pressure.ms5837] address: 0x76 (118) is already used by [pca9685] on I²C "
            "bus 1; a TOML number is decimal unless written 0x…",
        ),
        # `address = 28` is 0x1c: no BNO055 answers there, and the controller, taking it for a
        # dead IMU at start, ran without attitude.
        (
            {"imu__address": 28},
            "rov.toml [imu]: address must be a BNO055's, 0x28 (ADR low) or 0x29 (ADR high), got "
            "0x1c (28); a TOML number is decimal unless written 0x…",
        ),
        (
            {"pca9685__address": 40},
            "rov.toml [pca9685]: address must be a PCA9685's, 0x40–0x77 but not 0x70 (the All "
            "Call address every PCA9685 answers after a reset), got 0x28 (40); a TOML number is "
            "decimal unless written 0x…",
        ),
        # Every PCA9685 answers 0x70 after power-on or a supply dip: a chip strapped there would
        # have its writes land in every other chip that reset.
        (
            {"pca9685__address": 0x70},
            "rov.toml [pca9685]: address must be a PCA9685's, 0x40–0x77 but not 0x70",
        ),
        (
            {"pressure__sensor": "ads1115", "pca9685__address": 0x48},
            "rov.toml [pressure.ads1115] address: 0x48 (72) is already used by [pca9685]",
        ),
        # Addresses no such chip has (TOML read `76` and `48` as decimal): they failed only
        # at start, naming an address the file did not seem to hold.
        (
            {"pressure__ms5837__address": 76},
            "rov.toml [pressure.ms5837]: address must be the MS5837's, 0x76 (fixed on the chip), "
            "got 0x4c (76); a TOML number is decimal unless written 0x…",
        ),
        (
            {"pressure__ads1115__address": 48},
            "rov.toml [pressure.ads1115]: address must be an ADS1115's, 0x48–0x4b (by its ADDR "
            "pin), got 0x30 (48); a TOML number is decimal unless written 0x…",
        ),
        # An active-low probe on GPIO 2 (SDA): gpiozero takes its pull-up, and the pin would
        # be taken from the bus every device is on.
        (
            {"leak__pin": 2, "leak__pull": "up", "leak__active_high": False},
            "rov.toml [leak] pin: GPIO 2 is SDA of I²C bus 1, which the board's devices are on",
        ),
        (
            {"leak__pin": 3, "i2c__bus": 3, "imu__bus": 1},
            "rov.toml [leak] pin: GPIO 3 is SCL of I²C bus 1",
        ),
        ({"gpio": {"pin": 3}}, "unknown table [gpio]"),
        # A table written as a value: before, the six board tables' messages left the file out.
        ({"i2c": 1}, "rov.toml [i2c] must be a table, got int"),
        ({"pca9685": "0x40"}, "rov.toml [pca9685] must be a table, got str"),
        ({"claw": 8}, "rov.toml [claw] must be a table, got int"),
        ({"imu": "bno055"}, "rov.toml [imu] must be a table, got str"),
        ({"leak": 27}, "rov.toml [leak] must be a table, got int"),
        ({"board": True}, "rov.toml [board] must be a table, got bool"),
        ({"thrusters": []}, "rov.toml [[thrusters]]: the layout is empty"),
    ],
)
def test_a_wrong_config_is_refused_with_the_key_and_the_reason(
    changes: dict[str, object], message: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        _load(**changes)
    assert message in str(caught.value)
    assert str(caught.value).startswith("rov.toml")


@pytest.mark.parametrize(
    "changes",
    [
        # The IMU on a bus of its own.
        {"imu__bus": 3, "imu__address": 0x29},
        # Only the pressure sensor chosen is on the bus.
        {"pca9685__address": 0x4B, "pressure__ads1115__address": 0x4B},
        {"imu__sensor": "none", "imu__address": 0x40},
    ],
)
def test_an_address_on_another_bus_or_of_a_device_not_fitted_is_no_conflict(
    changes: dict[str, object],
) -> None:
    _load(**changes)


def test_a_leak_probe_on_gpio_2_is_taken_when_i2c_bus_1_is_not_used() -> None:
    _load(leak__pin=2, leak__pull="up", leak__active_high=False, i2c__bus=3)


@pytest.mark.parametrize(
    ("watchdog_s", "reason"),
    [
        # P17's "0 disables" is for the simulator's bench: on a robot a dead link would leave
        # the thrusters running.
        ("0", "must be 0.1–10 s on a robot, got 0, which turns the link-loss failsafe off"),
        ("0.0", "must be 0.1–10 s on a robot, got 0, which turns the link-loss failsafe off"),
        ("7200", "must be 0.1–10 s on a robot, got 7200: a dead link would leave the thrusters"),
        ("10.5", "must be 0.1–10 s on a robot, got 10.5"),
        ("0.05", "must be 0.1–10 s on a robot, got 0.05"),
        ("1e-9", "must be 0.1–10 s on a robot, got 1e-09"),
    ],
)
def test_the_link_loss_failsafe_of_a_robot_is_bounded(
    tmp_path: Path, watchdog_s: str, reason: str
) -> None:
    path = tmp_path / "rov.toml"
    text = EXAMPLE.read_text(encoding="utf-8")
    path.write_text(text.replace("watchdog_s = 2.0", f"watchdog_s = {watchdog_s}"), "utf-8")
    with pytest.raises(ConfigError) as caught:
        load_pi_config(path)
    assert str(caught.value).startswith(f"{path} [controller] watchdog_s: {reason}")


@pytest.mark.parametrize("watchdog_s", ["nan", "inf", "-1", "-0.5"])
def test_a_link_loss_failsafe_that_is_no_duration_is_refused(
    tmp_path: Path, watchdog_s: str
) -> None:
    path = tmp_path / "rov.toml"
    text = EXAMPLE.read_text(encoding="utf-8")
    path.write_text(text.replace("watchdog_s = 2.0", f"watchdog_s = {watchdog_s}"), "utf-8")
    with pytest.raises(ConfigError, match=r"\[controller\]: watchdog_s must be ≥ 0") as caught:
        load_pi_config(path)
    assert str(caught.value).startswith(str(path))


@pytest.mark.parametrize("watchdog_s", [0.1, 2.0, 10.0])
def test_a_link_loss_failsafe_within_the_bounds_is_taken(tmp_path: Path, watchdog_s: float) -> None:
    path = tmp_path / "rov.toml"
    text = EXAMPLE.read_text(encoding="utf-8")
    path.write_text(text.replace("watchdog_s = 2.0", f"watchdog_s = {watchdog_s}"), "utf-8")
    assert load_pi_config(path).controller.watchdog_s == watchdog_s


def test_several_pwm_boards_share_one_bus() -> None:
    config = pi_config_from_mapping(two_pwm_boards_data(), "rov.toml")
    assert [pwm.address for pwm in config.pwm_boards] == [0x40, 0x41]
    boards = [config.pwm_board_index(esc.pca9685) for esc in config.escs]
    assert boards == [0, 0, 0, 0, 1, 1]
    assert [esc.channel for esc in config.escs] == [0, 1, 2, 3, 0, 1]  # channels 0, 1 twice
    assert config.pwm_board_index(config.claw.pca9685) == 1


def test_more_thrusters_than_one_pwm_board_has_channels() -> None:
    # 18 thrusters and a claw: 19 outputs, more than a PCA9685's 16.
    data = read_toml(EXAMPLE)
    data["thrusters"] = [{"name": f"t{index}", "angle_deg": 20.0 * index} for index in range(18)]
    data["pca9685"] = [{"address": 0x40}, {"address": 0x41}]
    data["esc"] = {
        f"t{index}": {"channel": index % 16, "pca9685": 0x40 if index < 16 else 0x41}
        for index in range(18)
    }
    data["claw"].update(channel=2, pca9685=0x41)
    config = pi_config_from_mapping(data, "rov.toml")
    assert len(config.escs) == 18
    assert [config.pwm_board_index(esc.pca9685) for esc in config.escs] == [0] * 16 + [1, 1]


def _two_boards(**changes: object) -> None:
    data = two_pwm_boards_data()
    for dotted, value in changes.items():
        *path, key = dotted.split("__")
        table: Any = data
        for name in path:
            table = table[int(name)] if isinstance(table, list) else table[name]
        table[key] = value
    pi_config_from_mapping(data, "rov.toml")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"pca9685__1__address": 0x40},
            "rov.toml [[pca9685]] #2 address: 0x40 (64) is already used by [[pca9685]] #1 "
            "on I²C bus 1",
        ),
        (
            {"pca9685__1__address": 0x76},
            "rov.toml [pressure.ms5837] address: 0x76 (118) is already used by [[pca9685]] #2",
        ),
        (
            {"esc__vertical_left__pca9685": 0x42},
            "rov.toml [esc.vertical_left] pca9685: no PCA9685 at 0x42; the PWM boards are at "
            "0x40, 0x41",
        ),
        (
            {"claw__pca9685": 0x60},
            "rov.toml [claw] pca9685: no PCA9685 at 0x60; the PWM boards are at 0x40, 0x41",
        ),
        (
            {"esc__vertical_right__channel": 0},
            "rov.toml [esc.vertical_right] channel: 0 of the PCA9685 at 0x41 is already used by "
            "[esc.vertical_left]",
        ),
        (
            {"pca9685__1__frequency_hz": 600.0},
            "rov.toml [[pca9685]] #2 frequency_hz: a 1900 µs pulse does not fit in the 1638 µs "
            "period of 600 Hz",
        ),
        ({"pca9685__1__adress": 0x42}, "rov.toml [[pca9685]] #2: unknown key 'adress'"),
    ],
)
def test_a_wrong_pwm_board_list_is_refused_naming_the_table_and_the_key(
    changes: dict[str, object], message: str
) -> None:
    with pytest.raises(ConfigError) as caught:
        _two_boards(**changes)
    assert str(caught.value).startswith(message)


def test_an_empty_list_of_pwm_boards_is_refused() -> None:
    data = two_pwm_boards_data()
    data["pca9685"] = []
    with pytest.raises(ConfigError, match=r"rov.toml \[\[pca9685\]\]: no PWM board"):
        pi_config_from_mapping(data, "rov.toml")


def test_the_pwm_boards_part_is_read_whatever_the_other_tables_hold(tmp_path: Path) -> None:
    path = tmp_path / "rov.toml"
    text = EXAMPLE.read_text(encoding="utf-8").replace("kp = 40", "kp = 400")
    path.write_text(text.replace("[board]", "[board]\nno_such_key = 1"), encoding="utf-8")
    with pytest.raises(ConfigError, match="kp must be in 0–99"):
        load_pi_config(path)
    config = load_pi_outputs_config(path)
    assert [esc.channel for esc in config.escs] == [0, 1, 2, 3, 4, 5]
    assert config.claw.channel == 8
    path.write_text(text.replace("channel = 8", "channel = 5"), encoding="utf-8")
    with pytest.raises(ConfigError, match=r"\[claw\] channel: 5 is already used by"):
        load_pi_outputs_config(path)


def test_a_file_that_is_not_toml(tmp_path: Path) -> None:
    path = tmp_path / "rov.toml"
    path.write_text("[pca9685\naddress = 1\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_pi_config(path)


def _comment_of(text: str, table: tuple[str, ...], key: str) -> str:
    """The comment on the line of ``key`` in ``[table]`` of a TOML text ('' if none)."""
    current: tuple[str, ...] = ()
    for line in text.splitlines():
        header = re.fullmatch(r"\[([\w.]+)\]\s*(#.*)?", line.strip())
        if header:
            current = tuple(header.group(1).split("."))
        elif current == table and re.match(rf"{re.escape(key)}\s*=", line):
            return line.partition("#")[2]
    return ""


def test_the_example_names_the_default_of_every_key_it_sets_otherwise() -> None:
    # Regression: rov.toml said every key showed its default, but leak_action = "stop" is not
    # (the default, "none", only reports a leak): a team that pruned the "default" lines of its
    # copy left its robot driving on after a leak. The layout and the ESCs are the vehicle's own.
    data = read_toml(EXAMPLE)
    text = EXAMPLE.read_text(encoding="utf-8")
    example = pi_config_from_mapping(data, "rov.toml")
    for name, table in data.items():
        if name in ("thrusters", "esc"):
            continue
        tables: dict[tuple[str, ...], Any] = {(name,): table}
        tables.update(
            {(name, key): value for key, value in table.items() if isinstance(value, dict)}
        )
        for path, values in tables.items():
            for key in [key for key, value in values.items() if not isinstance(value, dict)]:
                without = copy.deepcopy(data)
                holder = without
                for part in path:
                    holder = holder[part]
                del holder[key]
                try:
                    is_default = pi_config_from_mapping(without, "rov.toml") == example
                except ConfigError:
                    is_default = False
                comment = _comment_of(text, path, key)
                assert is_default or "default" in comment, f"[{'.'.join(path)}] {key}: {comment!r}"
