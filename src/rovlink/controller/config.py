"""The controller's configuration: dataclasses with documented defaults, loaded from TOML.

A configuration file holds any of the tables below; every key is optional and a missing key keeps
its default. Unknown tables or keys, wrong types and out-of-range values are errors that name the
file, the table and the key, so nothing is half-applied::

    [controller]
    max_pwm = 200
    leak_action = "surface"

    [depth_pid]
    kp = 30

    [[thrusters]]          # a layout replaces the default one as a whole
    name = "left"
    angle_deg = 0.0
    y_m = -0.15

:func:`config_reference` renders every key with its default and meaning (``docs/controller.md``).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from rovlink.protocol import ALGORITHMS
from rovlink.protocol.text_enum import StrEnum

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - the Python 3.10 CI job
    import tomli as tomllib

__all__ = [
    "DEFAULT_THRUSTERS",
    "ConfigError",
    "ControllerConfig",
    "DepthCalibration",
    "DepthPidConfig",
    "LeakAction",
    "ThrusterSpec",
    "config_from_mapping",
    "config_reference",
    "dataclass_from_table",
    "load_config",
    "parameter_doc",
    "read_toml",
    "table_reference",
]

_T = TypeVar("_T")


#: The largest config file read, bytes.
_MAX_CONFIG_BYTES = 1 << 20


class ConfigError(ValueError):
    """A configuration that cannot be used; the message names the file, table and key."""


class LeakAction(StrEnum):
    """What the controller does when the leak sensor fires (P14)."""

    NONE = "none"  # report only, through q.l
    STOP = "stop"  # as #stop!
    SURFACE = "surface"  # horizontal power 0, full up thrust, stays unlocked


def parameter_doc(text: str) -> dict[str, str]:
    """Field metadata: the documentation of a configuration key."""
    return {"doc": text}


_doc = parameter_doc  # short, for the many field definitions below


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise ConfigError(message)


@dataclass(frozen=True, slots=True)
class DepthCalibration:
    """Raw pressure reading to depth (P13): depth[m] = (raw − zero_raw) · k / 10000."""

    zero_raw: int = field(
        default=20, metadata=_doc("raw reading at the surface (default `sdz`), 0–1024")
    )
    k: int = field(
        default=200,
        metadata=_doc("depth coefficient (default `sdk`), 0–10000; 200 = 2 cm per count"),
    )
    max_depth_cm: int = field(
        default=0,
        metadata=_doc(
            "deepest allowed depth, cm; past it down thrust is refused and deeper `mvd` targets "
            "are dropped; 0 = off",
        ),
    )

    def __post_init__(self) -> None:
        _require(0 <= self.zero_raw <= 1024, f"zero_raw must be in 0–1024, got {self.zero_raw}")
        _require(0 <= self.k <= 10000, f"k must be in 0–10000, got {self.k}")
        _require(
            0 <= self.max_depth_cm <= 9999,
            f"max_depth_cm must be in 0–9999, got {self.max_depth_cm}",
        )


@dataclass(frozen=True, slots=True)
class DepthPidConfig:
    """The depth PID (P10): integer gains 0–99 as `mvpdp`/`mvpdi`/`mvpidd` set them, and scales.

    The physical gains are gain × scale; the output is vertical thrust in % (+ up).
    """

    kp: int = field(default=40, metadata=_doc("proportional gain at reset (`mvpdp`), 0–99"))
    ki: int = field(default=30, metadata=_doc("integral gain at reset (`mvpdi`), 0–99"))
    kd: int = field(default=20, metadata=_doc("derivative gain at reset (`mvpidd`), 0–99"))
    kp_scale: float = field(
        default=0.05, metadata=_doc("% thrust per cm of depth error, per unit of kp")
    )
    ki_scale: float = field(
        default=0.005, metadata=_doc("% thrust per cm·s of accumulated error, per unit of ki")
    )
    kd_scale: float = field(
        default=0.1, metadata=_doc("% thrust per cm/s of vertical speed, per unit of kd")
    )
    derivative_filter_s: float = field(
        default=0.5,
        metadata=_doc("time constant of the low-pass filter on the measured vertical speed, s"),
    )

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd"):
            value = getattr(self, name)
            _require(0 <= value <= 99, f"{name} must be in 0–99, got {value}")
        for name in ("kp_scale", "ki_scale", "kd_scale", "derivative_filter_s"):
            value = getattr(self, name)
            _require(
                math.isfinite(value) and value >= 0, f"{name} must be finite and ≥ 0, got {value}"
            )


@dataclass(frozen=True, slots=True)
class ThrusterSpec:
    """One thruster of the frame: its output index is its position in the layout."""

    name: str = field(default="", metadata=_doc("a name for logs and the simulator"))
    vertical: bool = field(
        default=False, metadata=_doc("true for a vertical thruster (+ duty pushes up)")
    )
    angle_deg: float = field(
        default=0.0,
        metadata=_doc(
            "horizontal thruster: direction + duty pushes the vehicle, ° clockwise from the bow"
        ),
    )
    x_m: float = field(
        default=0.0, metadata=_doc("position forward of the centre, m (used by the simulator)")
    )
    y_m: float = field(
        default=0.0, metadata=_doc("position to starboard of the centre, m (used by the simulator)")
    )

    def __post_init__(self) -> None:
        _require(bool(self.name), "every thruster needs a name")
        for name in ("angle_deg", "x_m", "y_m"):
            value = getattr(self, name)
            _require(math.isfinite(value), f"{name} must be finite, got {value}")


#: Four vectored horizontal thrusters at 45° and two vertical ones (P11).
DEFAULT_THRUSTERS: tuple[ThrusterSpec, ...] = (
    ThrusterSpec("front_left", angle_deg=45.0, x_m=0.2, y_m=-0.15),
    ThrusterSpec("front_right", angle_deg=315.0, x_m=0.2, y_m=0.15),
    ThrusterSpec("rear_left", angle_deg=315.0, x_m=-0.2, y_m=-0.15),
    ThrusterSpec("rear_right", angle_deg=45.0, x_m=-0.2, y_m=0.15),
    ThrusterSpec("vertical_left", vertical=True, y_m=-0.2),
    ThrusterSpec("vertical_right", vertical=True, y_m=0.2),
)


@dataclass(frozen=True, slots=True)
class ControllerConfig:
    """Everything configurable in the controller; the defaults suit the default simulated ROV."""

    tick_hz: float = field(default=100.0, metadata=_doc("control loop rate, Hz (1–1000)"))
    max_pwm: int = field(default=255, metadata=_doc("PWM duty cap at reset (`mgmp`), 0–255"))
    watchdog_s: float = field(
        default=2.0,
        metadata=_doc(
            "link-loss failsafe: stop when no valid frame arrives for this long, s; 0 = off"
        ),
    )
    claw_pulse_ms: int = field(
        default=50, metadata=_doc("how long `h+`/`h-` run the claw motor, ms (1–10000)")
    )
    leak_action: LeakAction = field(
        default=LeakAction.NONE,
        metadata=_doc("on a leak: `none` (report only), `stop` (as `#stop!`), `surface`"),
    )
    checksum_algorithm: str = field(
        default="crc8",
        metadata=_doc("checksum used while checksum mode is on: " + ", ".join(ALGORITHMS)),
    )
    depth: DepthCalibration = field(default_factory=DepthCalibration)
    depth_pid: DepthPidConfig = field(default_factory=DepthPidConfig)
    thrusters: tuple[ThrusterSpec, ...] = DEFAULT_THRUSTERS

    def __post_init__(self) -> None:
        _require(
            math.isfinite(self.tick_hz) and 1 <= self.tick_hz <= 1000,
            f"tick_hz must be in 1–1000, got {self.tick_hz}",
        )
        _require(0 <= self.max_pwm <= 255, f"max_pwm must be in 0–255, got {self.max_pwm}")
        _require(
            math.isfinite(self.watchdog_s) and self.watchdog_s >= 0,
            f"watchdog_s must be ≥ 0, got {self.watchdog_s}",
        )
        _require(
            1 <= self.claw_pulse_ms <= 10000,
            f"claw_pulse_ms must be in 1–10000, got {self.claw_pulse_ms}",
        )
        _require(
            self.checksum_algorithm in ALGORITHMS,
            f"checksum_algorithm must be one of {', '.join(ALGORITHMS)}, "
            f"got {self.checksum_algorithm!r}",
        )
        _require(bool(self.thrusters), "the thruster layout is empty")
        names = [thruster.name for thruster in self.thrusters]
        _require(len(set(names)) == len(names), f"thruster names must differ: {names}")

    @property
    def tick_s(self) -> float:
        """The control period, s."""
        return 1.0 / self.tick_hz


# -- TOML ----------------------------------------------------------------------------------------

#: TOML table name → the dataclass it configures (``thrusters`` is an array of tables).
_TABLES: dict[str, type[Any]] = {
    "controller": ControllerConfig,
    "depth": DepthCalibration,
    "depth_pid": DepthPidConfig,
    "thrusters": ThrusterSpec,
}


def _scalar_fields(cls: type[Any]) -> dict[str, type[Any]]:
    hints = typing.get_type_hints(cls)
    scalars = (bool, int, float, str)
    return {
        item.name: hints[item.name]
        for item in dataclasses.fields(cls)
        if isinstance(hints[item.name], type) and issubclass(hints[item.name], scalars)
    }


def _convert(value: object, expected: type[Any], where: str) -> object:
    if issubclass(expected, StrEnum):
        allowed = [member.value for member in expected]
        if isinstance(value, str) and value in allowed:
            return expected(value)
        raise ConfigError(f"{where} must be one of {', '.join(allowed)}, got {value!r}")
    if expected is float and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    # bool is an int in Python, but not in TOML: keep them apart.
    if isinstance(value, expected) and (expected is bool) == isinstance(value, bool):
        return value
    raise ConfigError(f"{where} must be {expected.__name__}, got {type(value).__name__} {value!r}")


def dataclass_from_table(
    cls: type[_T], table: Mapping[str, object], where: str, **nested: object
) -> _T:
    """Make ``cls`` from one TOML table of scalar keys; ``nested`` gives its non-scalar fields.

    ``where`` names the table in error messages, e.g. ``"robot.toml [depth_pid]"``.
    """
    if not isinstance(table, Mapping):
        raise ConfigError(f"{where} must be a table, got {type(table).__name__}")
    fields = _scalar_fields(cls)
    values: dict[str, object] = dict(nested)
    for key, value in table.items():
        if key not in fields:
            known = ", ".join(sorted(fields))
            raise ConfigError(f"{where}: unknown key {key!r}; expected one of: {known}")
        values[key] = _convert(value, fields[key], f"{where} {key}")
    try:
        return cls(**values)
    except ValueError as error:  # ConfigError, or a plain ValueError of a class such as the sim's
        raise ConfigError(f"{where}: {error}") from None


def read_toml(path: Path | str) -> dict[str, Any]:
    """The parsed TOML file, or :class:`ConfigError` naming the file and what is wrong.

    Whatever the file holds (binary data, another encoding, a device that never ends), the
    error is a :class:`ConfigError`, never a decoding exception.
    """
    path = Path(path)
    try:
        with path.open("rb") as stream:
            # Bounded: a config file is small, and --config /dev/zero must not eat the memory.
            data = stream.read(_MAX_CONFIG_BYTES + 1)
    except OSError as error:
        raise ConfigError(f"{path}: cannot read: {error.strerror or error}") from None
    if len(data) > _MAX_CONFIG_BYTES:
        raise ConfigError(
            f"{path}: larger than {_MAX_CONFIG_BYTES // 1024} KiB, not a TOML config file"
        )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as error:
        line = data.count(b"\n", 0, error.start) + 1
        raise ConfigError(
            f"{path}: not UTF-8 text (byte 0x{data[error.start]:02x} on line {line}), "
            "so not a TOML file"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{path}: not valid TOML: {error}") from None
    except RecursionError:
        raise ConfigError(f"{path}: not valid TOML: nested too deeply") from None


def config_from_mapping(
    data: Mapping[str, Any], source: str = "config", *, other_tables: Sequence[str] = ()
) -> ControllerConfig:
    """The controller configuration in parsed TOML ``data``.

    ``other_tables`` are top-level tables that belong to someone else (the simulator's
    ``vehicle``, for one) and are skipped; any other unknown table is an error.
    """
    for name in data:
        if name not in _TABLES and name not in other_tables:
            known = ", ".join([*_TABLES, *other_tables])
            raise ConfigError(f"{source}: unknown table [{name}]; expected one of: {known}")
    depth = dataclass_from_table(DepthCalibration, data.get("depth", {}), f"{source} [depth]")
    pid = dataclass_from_table(DepthPidConfig, data.get("depth_pid", {}), f"{source} [depth_pid]")
    thrusters = DEFAULT_THRUSTERS
    if "thrusters" in data:
        tables = data["thrusters"]
        if not isinstance(tables, list):
            raise ConfigError(f"{source}: thrusters must be an array of tables [[thrusters]]")
        if not tables:
            raise ConfigError(
                f"{source} [[thrusters]]: the layout is empty: one table for each thruster"
            )
        thrusters = tuple(
            dataclass_from_table(ThrusterSpec, table, f"{source} [[thrusters]] #{index + 1}")
            for index, table in enumerate(tables)
        )
        _refuse_repeated_names(thrusters, source)
    return dataclass_from_table(
        ControllerConfig,
        data.get("controller", {}),
        f"{source} [controller]",
        depth=depth,
        depth_pid=pid,
        thrusters=thrusters,
    )


def _refuse_repeated_names(thrusters: Sequence[ThrusterSpec], source: str) -> None:
    """A name given twice, named with both tables: a board finds each thruster's output by its
    name, so a copied table left unrenamed must be told apart from a layout error."""
    first_table: dict[str, int] = {}
    for number, thruster in enumerate(thrusters, start=1):
        if thruster.name in first_table:
            raise ConfigError(
                f"{source} [[thrusters]] #{number} name: {thruster.name!r} is already the name "
                f"of [[thrusters]] #{first_table[thruster.name]}; every thruster needs its own"
            )
        first_table[thruster.name] = number


def load_config(path: Path | str, *, other_tables: Sequence[str] = ()) -> ControllerConfig:
    """The controller configuration in a TOML file (see the module docstring)."""
    return config_from_mapping(read_toml(path), str(path), other_tables=other_tables)


def table_reference(heading: str, instance: object) -> str:
    """A Markdown table of one TOML table's keys: name, default (from ``instance``), meaning."""
    lines = [f"### `{heading}`", "", "| key | default | meaning |", "|---|---|---|"]
    for item in dataclasses.fields(instance):  # type: ignore[arg-type]
        if "doc" in item.metadata:
            default = _toml_value(getattr(instance, item.name))
            lines.append(f"| `{item.name}` | `{default}` | {item.metadata['doc']} |")
    return "\n".join(lines) + "\n"


def config_reference() -> str:
    """Markdown tables of every key with its default and meaning, and the default layout."""
    defaults = ControllerConfig()
    layout = "\n".join(
        "[[thrusters]]\n"
        + "\n".join(
            f"{item.name} = {_toml_value(getattr(spec, item.name))}"
            for item in dataclasses.fields(spec)
        )
        + "\n"
        for spec in DEFAULT_THRUSTERS
    )
    return (
        "\n".join(
            [
                table_reference("[controller]", defaults),
                table_reference("[depth]", defaults.depth),
                table_reference("[depth_pid]", defaults.depth_pid),
                table_reference("[[thrusters]]", ThrusterSpec(name="required")),
                "The default layout (a `[[thrusters]]` list replaces it as a whole; the output "
                "index of a thruster is its place in the list):",
                "",
                "```toml",
                layout + "```",
            ]
        )
        + "\n"
    )


def _toml_value(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)
