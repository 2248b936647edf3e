"""The TOML configuration: every default documented, clear errors, nothing half-applied."""

from __future__ import annotations

from pathlib import Path

import pytest

from rovlink.controller import (
    DEFAULT_THRUSTERS,
    ConfigError,
    ControllerConfig,
    LeakAction,
    config_reference,
    load_config,
)

DOCS = Path(__file__).resolve().parents[2] / "docs" / "controller.md"


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robot.toml"
    path.write_text(text)
    return path


def test_an_empty_file_gives_the_defaults(tmp_path: Path) -> None:
    assert load_config(_write(tmp_path, "")) == ControllerConfig()


def test_every_table_is_read(tmp_path: Path) -> None:
    config = load_config(
        _write(
            tmp_path,
            """
[controller]
tick_hz = 50
max_pwm = 200
watchdog_s = 1
claw_pulse_ms = 80
leak_action = "surface"
checksum_algorithm = "sum8"

[depth]
zero_raw = 30
k = 250
max_depth_cm = 1500

[depth_pid]
kp = 1
ki = 2
kd = 3
kp_scale = 0.5
derivative_filter_s = 0.2

[[thrusters]]
name = "left"
y_m = -0.2

[[thrusters]]
name = "right"
y_m = 0.2

[[thrusters]]
name = "up"
vertical = true
""",
        )
    )
    assert (config.tick_hz, config.max_pwm, config.watchdog_s) == (50.0, 200, 1.0)
    assert (config.claw_pulse_ms, config.leak_action) == (80, LeakAction.SURFACE)
    assert config.checksum_algorithm == "sum8"
    assert (config.depth.zero_raw, config.depth.k, config.depth.max_depth_cm) == (30, 250, 1500)
    pid = config.depth_pid
    assert (pid.kp, pid.ki, pid.kd, pid.kp_scale, pid.derivative_filter_s) == (1, 2, 3, 0.5, 0.2)
    assert pid.ki_scale == ControllerConfig().depth_pid.ki_scale
    assert [spec.name for spec in config.thrusters] == ["left", "right", "up"]
    assert config.thrusters[2].vertical
    assert config.tick_s == 0.02


def test_the_default_layout_is_four_vectored_thrusters_at_45_degrees() -> None:
    horizontal = [spec for spec in DEFAULT_THRUSTERS if not spec.vertical]
    assert sorted(spec.angle_deg % 90 for spec in horizontal) == [45.0] * 4
    assert len([spec for spec in DEFAULT_THRUSTERS if spec.vertical]) == 2


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("[controler]\n", ["robot.toml", "unknown table [controler]"]),
        ("[controller]\nmax_pwn = 1\n", ["[controller]", "unknown key 'max_pwn'", "max_pwm"]),
        ("[controller]\nmax_pwm = 256\n", ["[controller]", "max_pwm", "0–255", "256"]),
        ("[controller]\nmax_pwm = 2.5\n", ["[controller] max_pwm", "int", "float"]),
        ("[controller]\nmax_pwm = true\n", ["max_pwm", "int", "bool"]),
        ('[controller]\nleak_action = "sink"\n', ["leak_action", "none, stop, surface", "sink"]),
        ('[controller]\nchecksum_algorithm = "md5"\n', ["checksum_algorithm", "crc8"]),
        ("[controller]\nwatchdog_s = -1\n", ["watchdog_s", "≥ 0"]),
        ("[controller]\ntick_hz = 0\n", ["tick_hz"]),
        ("[depth]\nk = 20000\n", ["[depth]", "k must be in 0–10000"]),
        ("[depth_pid]\nkp = 100\n", ["[depth_pid]", "kp must be in 0–99"]),
        ("[depth_pid]\nkd_scale = -1.0\n", ["kd_scale"]),
        ("[[thrusters]]\nangle_deg = 3\n", ["[[thrusters]] #1", "needs a name"]),
        (
            '[[thrusters]]\nname = "a"\n[[thrusters]]\nname = "b"\n[[thrusters]]\nname = "a"\n',
            ["[[thrusters]] #3 name", "'a' is already the name of [[thrusters]] #1"],
        ),
        ("thrusters = 3\n", ["array of tables"]),
        ("[controller\n", ["not valid TOML"]),
        ("controller = 1\n", ["[controller] must be a table"]),
    ],
)
def test_errors_name_the_file_table_and_key(tmp_path: Path, text: str, words: list[str]) -> None:
    with pytest.raises(ConfigError) as caught:
        load_config(_write(tmp_path, text))
    message = str(caught.value)
    for word in words:
        assert word in message, message


def test_a_missing_file_is_a_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read"):
        load_config(tmp_path / "absent.toml")


def test_other_tables_can_be_allowed(tmp_path: Path) -> None:
    path = _write(tmp_path, "[vehicle]\nmass_kg = 3\n")
    with pytest.raises(ConfigError):
        load_config(path)
    assert load_config(path, other_tables=("vehicle",)) == ControllerConfig()


def test_the_reference_lists_every_key_with_its_default() -> None:
    reference = config_reference()
    for key, default in [
        ("max_pwm", "255"),
        ("watchdog_s", "2.0"),
        ("claw_pulse_ms", "50"),
        ("leak_action", '"none"'),
        ("max_depth_cm", "0"),
        ("kp", "40"),
        ("zero_raw", "20"),
        ("k", "200"),
        ("angle_deg", "0.0"),
    ]:
        assert f"| `{key}` | `{default}` |" in reference


def test_docs_contain_the_current_reference() -> None:
    # docs/controller.md is checked against the code, so its defaults cannot go stale.
    assert config_reference() in DOCS.read_text(encoding="utf-8")


def test_the_documented_default_layout_parses_back_to_the_default(tmp_path: Path) -> None:
    reference = config_reference()
    layout = reference.split("```toml\n", 1)[1].split("```", 1)[0]
    assert load_config(_write(tmp_path, layout)).thrusters == DEFAULT_THRUSTERS


def _read_error(path: Path) -> str:
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    return str(caught.value)


def test_a_binary_file_is_a_config_error_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_bytes(bytes(range(256)) * 4)
    message = _read_error(path)
    assert str(path) in message
    assert "not UTF-8 text" in message


def test_a_non_utf8_file_is_a_config_error_naming_the_byte_and_line(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_bytes("[controller]\nname = 'Tiefsee-Roboter für 20 m'\n".encode("latin-1"))
    message = _read_error(path)
    assert message == f"{path}: not UTF-8 text (byte 0xfc on line 2), so not a TOML file"


def test_utf8_text_that_is_not_toml_is_a_config_error(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_bytes(b"\x00\x01binary but valid UTF-8\n")
    assert "not valid TOML" in _read_error(path)


def test_a_directory_is_a_config_error(tmp_path: Path) -> None:
    message = _read_error(tmp_path)
    assert message.startswith(f"{tmp_path}: cannot read: ")


def test_a_missing_file_is_a_config_error_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "absent.toml"
    assert _read_error(path) == f"{path}: cannot read: No such file or directory"


def test_a_huge_file_is_refused_without_reading_it_all(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_bytes(b"# comment\n" * 200_000)
    assert "larger than 1024 KiB" in _read_error(path)
