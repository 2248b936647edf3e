"""The board's configuration, ``rov.toml``: the controller's tables plus the board's own.

The controller's tables (``[controller]``, ``[depth]``, ``[depth_pid]``, ``[[thrusters]]``) are
read by :func:`rovlink.controller.config_from_mapping`; this module reads the rest and checks
the whole: every thruster of the layout has an ESC output, no two outputs share a channel, no
two devices share an address on one bus, pulses fit the PWM period. A wrong file is refused
with the file, the table, the key and the reason. ``docs/hardware.md`` has a complete,
commented example.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rovlink.board.pi.ads1115 import DATA_RATES_SPS, FULL_SCALES_V
from rovlink.board.pi.bno055 import PLACEMENTS
from rovlink.board.pi.ms5837 import OVERSAMPLING, Ms5837Model
from rovlink.board.pi.pca9685 import (
    ALL_CALL_ADDRESS,
    CHANNELS,
    DEFAULT_OSCILLATOR_HZ,
    FIRST_ADDRESS,
    prescale_for,
)
from rovlink.board.pi.pressure import MIN_SCALE_K
from rovlink.board.watchdog_bounds import board_watchdog_problem
from rovlink.controller import ControllerConfig, config_from_mapping
from rovlink.controller.config import (
    ConfigError,
    dataclass_from_table,
    parameter_doc,
    read_toml,
    table_reference,
)
from rovlink.protocol.text_enum import StrEnum

__all__ = [
    "MAX_STALE_AFTER_S",
    "STALE_AFTER_S",
    "Ads1115Config",
    "BoardConfig",
    "ClawConfig",
    "ClawKind",
    "EscConfig",
    "I2cBackend",
    "I2cConfig",
    "ImuConfig",
    "ImuKind",
    "LeakConfig",
    "Ms5837Config",
    "Pca9685Config",
    "PiConfig",
    "PressureConfig",
    "PressureKind",
    "load_pi_config",
    "load_pi_outputs_config",
    "pi_config_from_mapping",
    "pi_config_reference",
]

_doc = parameter_doc
_MIN_PULSE_US = 500.0
#: The ``pca9685`` key of an output's table.
_PCA9685_KEY_DOC = (
    "the address of its PCA9685 when there are several (`[[pca9685]]`); -1: the first one"
)
_MAX_PULSE_US = 2500.0


def _require(condition: bool, message: str) -> None:
    if not condition:
        raise ConfigError(message)


def _check_address(name: str, address: int) -> None:
    _require(0x03 <= address <= 0x77, f"{name} must be an I²C address 0x03–0x77, got {address}")


def _check_pulses(**pulses_us: float) -> None:
    for name, value in pulses_us.items():
        _require(
            math.isfinite(value) and _MIN_PULSE_US <= value <= _MAX_PULSE_US,
            f"{name} must be {_MIN_PULSE_US:g}–{_MAX_PULSE_US:g} µs, got {value}",
        )


class I2cBackend(StrEnum):
    """What carries the I²C transactions."""

    SMBUS2 = "smbus2"  # /dev/i2c-N through smbus2: the real bus
    FAKE = "fake"  # simulated devices in memory: for tests and a dry run without hardware


class ClawKind(StrEnum):
    """How the claw is driven."""

    NONE = "none"
    MOTOR = "motor"  # a motor behind an ESC or motor driver: h+/h- run it for claw_pulse_ms
    SERVO = "servo"  # a positional servo: h+/h- move it one step


class PressureKind(StrEnum):
    """The pressure sensor."""

    MS5837 = "ms5837"
    ADS1115 = "ads1115"


class ImuKind(StrEnum):
    """The IMU."""

    BNO055 = "bno055"
    NONE = "none"  # reports level, heading 0


@dataclass(frozen=True, slots=True)
class I2cConfig:
    """``[i2c]``: the bus every I²C device is on."""

    bus: int = field(default=1, metadata=_doc("bus number: /dev/i2c-N (1 on a Raspberry Pi)"))
    backend: I2cBackend = field(
        default=I2cBackend.SMBUS2,
        metadata=_doc(
            "`smbus2` (the real bus) or `fake` (simulated devices, for tests and a dry run on "
            "a desktop: nothing reaches hardware, and the leak pin is gpiozero's mock pin)"
        ),
    )
    fake_log: str = field(
        default="",
        metadata=_doc("`fake` only: a file that gets one JSON line per I²C transaction"),
    )

    def __post_init__(self) -> None:
        _require(0 <= self.bus <= 255, f"bus must be 0–255, got {self.bus}")
        _require(
            not self.fake_log or self.backend is I2cBackend.FAKE,
            'fake_log is for backend = "fake" only',
        )


@dataclass(frozen=True, slots=True)
class Pca9685Config:
    """``[pca9685]``: the PWM board of the ESCs and the claw."""

    address: int = field(
        default=0x40,
        metadata=_doc(
            "I²C address: 0x40 unless re-strapped, 0x40–0x77 but not 0x70 (the All Call "
            "address every PCA9685 answers after a reset)"
        ),
    )
    frequency_hz: float = field(
        default=50.0, metadata=_doc("pulse frequency, Hz (50 for ESCs and servos)")
    )
    oscillator_hz: float = field(
        default=DEFAULT_OSCILLATOR_HZ,
        metadata=_doc(
            "the chip's oscillator, Hz: nominal 25 MHz, real chips ±5 %; measure a pulse and set "
            "this so that neutral is 1500 µs"
        ),
    )
    check_interval_s: float = field(
        default=0.1,
        metadata=_doc(
            "read MODE1 and PRE_SCALE back this often to find a chip reset by a supply dip "
            "(two one-byte reads); a reset found is started again at neutral and stops and "
            "locks the motors; 0: never"
        ),
    )

    def __post_init__(self) -> None:
        _check_address("address", self.address)
        _require(
            self.address >= FIRST_ADDRESS and self.address != ALL_CALL_ADDRESS,
            f"address must be a PCA9685's, {FIRST_ADDRESS:#04x}–0x77 but not "
            f"{ALL_CALL_ADDRESS:#04x} (the All Call address every PCA9685 answers after a "
            f"reset), got {self.address:#04x} ({self.address}); a TOML number is decimal "
            "unless written 0x…",
        )
        _require(
            self.check_interval_s == 0
            or (math.isfinite(self.check_interval_s) and 0.01 <= self.check_interval_s <= 60),
            f"check_interval_s must be 0 (never) or 0.01–60, got {self.check_interval_s}",
        )
        _require(
            math.isfinite(self.oscillator_hz) and 20e6 <= self.oscillator_hz <= 30e6,
            f"oscillator_hz must be 20e6–30e6, got {self.oscillator_hz}",
        )
        try:
            prescale_for(self.frequency_hz, self.oscillator_hz)
        except ValueError as error:
            raise ConfigError(f"frequency_hz: {error}") from None


@dataclass(frozen=True, slots=True)
class EscConfig:
    """``[esc.<thruster name>]``: one thruster's ESC."""

    channel: int = field(default=-1, metadata=_doc("PCA9685 output 0–15 (required)"))
    pca9685: int = field(default=-1, metadata=_doc(_PCA9685_KEY_DOC))
    reversed: bool = field(
        default=False, metadata=_doc("true if + duty must give a pulse below neutral")
    )
    min_us: float = field(default=1100.0, metadata=_doc("pulse at full reverse, µs"))
    neutral_us: float = field(default=1500.0, metadata=_doc("pulse at rest (arms the ESC), µs"))
    max_us: float = field(default=1900.0, metadata=_doc("pulse at full forward, µs"))

    def __post_init__(self) -> None:
        _require(0 <= self.channel < CHANNELS, f"channel must be 0–15, got {self.channel}")
        _check_pulses(min_us=self.min_us, neutral_us=self.neutral_us, max_us=self.max_us)
        _require(
            self.min_us < self.neutral_us < self.max_us,
            f"pulses must rise min_us < neutral_us < max_us, got "
            f"{self.min_us:g} < {self.neutral_us:g} < {self.max_us:g}",
        )


@dataclass(frozen=True, slots=True)
class ClawConfig:
    """``[claw]``: the claw's output."""

    kind: ClawKind = field(default=ClawKind.NONE, metadata=_doc("`none`, `motor` or `servo`"))
    channel: int = field(default=-1, metadata=_doc("PCA9685 output 0–15"))
    pca9685: int = field(default=-1, metadata=_doc(_PCA9685_KEY_DOC))
    open_us: float = field(
        default=1900.0, metadata=_doc("motor: pulse while opening; servo: fully open, µs")
    )
    close_us: float = field(
        default=1100.0, metadata=_doc("motor: pulse while closing; servo: fully closed, µs")
    )
    neutral_us: float = field(
        default=1500.0, metadata=_doc("motor: pulse at rest; servo: position at start, µs")
    )
    step_us: float = field(default=100.0, metadata=_doc("servo: travel per `h+`/`h-`, µs"))

    def __post_init__(self) -> None:
        if self.kind is ClawKind.NONE:
            return
        _require(0 <= self.channel < CHANNELS, f"channel must be 0–15, got {self.channel}")
        _check_pulses(open_us=self.open_us, close_us=self.close_us, neutral_us=self.neutral_us)
        _require(
            math.isfinite(self.step_us) and 0 < self.step_us <= 1000,
            f"step_us must be in (0, 1000], got {self.step_us}",
        )


#: Said with an address a chip cannot have: `i2cdetect` shows hexadecimal, TOML reads decimal.
_DECIMAL_HINT = "a TOML number is decimal unless written 0x…"
#: The MS5837's I²C address (fixed on the chip).
_MS5837_ADDRESS = 0x76
#: The ADS1115's I²C addresses, by its ADDR pin (GND, VDD, SDA, SCL).
_ADS1115_ADDRESSES = (0x48, 0x49, 0x4A, 0x4B)


@dataclass(frozen=True, slots=True)
class Ms5837Config:
    """``[pressure.ms5837]``: a Blue Robotics Bar30 (`30ba`) or Bar02 (`02ba`)."""

    model: Ms5837Model = field(default=Ms5837Model.BA30, metadata=_doc("`30ba` or `02ba`"))
    address: int = field(default=0x76, metadata=_doc("I²C address (fixed at 0x76 on the chip)"))
    oversampling: int = field(
        default=4096,
        metadata=_doc(
            "oversampling ratio: "
            + ", ".join(map(str, OVERSAMPLING))
            + " (the MS5837-30BA26's datasheet, the Bar30's part, stops at 4096)"
        ),
    )

    def __post_init__(self) -> None:
        _check_address("address", self.address)
        # The chip has one address. Another (`address = 76`, decimal: 0x4c) only failed at
        # start, naming an address the file did not seem to hold.
        _require(
            self.address == _MS5837_ADDRESS,
            f"address must be the MS5837's, {_MS5837_ADDRESS:#04x} (fixed on the chip), got "
            f"{self.address:#04x} ({self.address}); {_DECIMAL_HINT}",
        )
        _require(
            self.oversampling in OVERSAMPLING,
            f"oversampling must be one of {', '.join(map(str, OVERSAMPLING))}, "
            f"got {self.oversampling}",
        )


@dataclass(frozen=True, slots=True)
class Ads1115Config:
    """``[pressure.ads1115]``: an analog transducer on an ADS1115."""

    address: int = field(default=0x48, metadata=_doc("I²C address (0x48–0x4B by the ADDR pin)"))
    channel: int = field(default=0, metadata=_doc("input AIN0–AIN3"))
    full_scale_v: float = field(
        default=4.096, metadata=_doc("range, V: " + ", ".join(map(str, FULL_SCALES_V)))
    )
    data_rate_sps: int = field(
        default=128, metadata=_doc("samples/s: " + ", ".join(map(str, DATA_RATES_SPS)))
    )
    # The defaults are a 0.5–4.5 V transducer through the wiring guide's divider (10 kΩ over
    # 20 kΩ, × 2/3): the ADS1115 on 3.3 V sees 0.3333–3.0 V.
    min_volts: float = field(
        default=0.3333,
        metadata=_doc("ADC input at min_mbar, V: the transducer's output after the divider"),
    )
    max_volts: float = field(
        default=3.0,
        metadata=_doc(
            "ADC input at max_mbar, V: the transducer's output after the divider; at most "
            "full_scale_v"
        ),
    )
    min_mbar: float = field(default=0.0, metadata=_doc("pressure at min_volts, mbar"))
    max_mbar: float = field(default=10000.0, metadata=_doc("pressure at max_volts, mbar"))

    def __post_init__(self) -> None:
        _check_address("address", self.address)
        _require(
            self.address in _ADS1115_ADDRESSES,
            f"address must be an ADS1115's, 0x48–0x4b (by its ADDR pin), got "
            f"{self.address:#04x} ({self.address}); {_DECIMAL_HINT}",
        )
        _require(0 <= self.channel <= 3, f"channel must be 0–3, got {self.channel}")
        _require(
            self.full_scale_v in FULL_SCALES_V,
            f"full_scale_v must be one of {', '.join(map(str, FULL_SCALES_V))}, "
            f"got {self.full_scale_v}",
        )
        _require(
            self.data_rate_sps in DATA_RATES_SPS,
            f"data_rate_sps must be one of {', '.join(map(str, DATA_RATES_SPS))}, "
            f"got {self.data_rate_sps}",
        )
        _require(
            self.min_volts < self.max_volts and self.min_mbar < self.max_mbar,
            "min_volts < max_volts and min_mbar < max_mbar are required",
        )
        # Above its full scale the ADC clips: every deeper pressure would read as max_volts.
        _require(
            self.max_volts <= self.full_scale_v,
            f"max_volts must be at most full_scale_v ({self.full_scale_v:g} V), "
            f"got {self.max_volts:g}",
        )


@dataclass(frozen=True, slots=True)
class PressureConfig:
    """``[pressure]``: the sensor and how its pressure maps onto the raw scale (P13)."""

    sensor: PressureKind = field(
        default=PressureKind.MS5837, metadata=_doc("`ms5837` or `ads1115`")
    )
    surface_mbar: float = field(
        default=1013.25,
        metadata=_doc(
            "pressure at the surface, mbar: raw reads [depth] zero_raw here (0 for a gauge "
            "transducer); `sdz` corrects it on the day"
        ),
    )
    density_kg_m3: float = field(
        default=997.0, metadata=_doc("water density, kg/m³: 997 fresh, 1029 sea")
    )
    ms5837: Ms5837Config = field(default_factory=Ms5837Config)
    ads1115: Ads1115Config = field(default_factory=Ads1115Config)

    def __post_init__(self) -> None:
        _require(
            math.isfinite(self.surface_mbar) and 0 <= self.surface_mbar <= 2000,
            f"surface_mbar must be 0–2000, got {self.surface_mbar}",
        )
        _require(
            math.isfinite(self.density_kg_m3) and 900 <= self.density_kg_m3 <= 1100,
            f"density_kg_m3 must be 900–1100, got {self.density_kg_m3}",
        )


#: The BNO055's I²C addresses: its ADR pin low, high.
_BNO055_ADDRESSES = (0x28, 0x29)


@dataclass(frozen=True, slots=True)
class ImuConfig:
    """``[imu]``: the IMU and its mounting."""

    sensor: ImuKind = field(default=ImuKind.BNO055, metadata=_doc("`bno055` or `none`"))
    bus: int = field(
        default=-1,
        metadata=_doc(
            "its own I²C bus number (a BNO055 on a software bus, for its clock stretching); "
            "-1: [i2c] bus"
        ),
    )
    address: int = field(default=0x28, metadata=_doc("I²C address (0x28, or 0x29 by ADR)"))
    placement: str = field(
        default="P1",
        metadata=_doc("mounting, the datasheet's placements P0–P7 (§3.4); P1 is the default"),
    )
    heading_offset_deg: float = field(
        default=0.0, metadata=_doc("added to the heading: the chip's yaw against the bow, °")
    )
    invert_roll: bool = field(
        default=False, metadata=_doc("negate roll so that + is starboard down")
    )
    invert_pitch: bool = field(default=False, metadata=_doc("negate pitch so that + is bow up"))
    poll_hz: float = field(default=20.0, metadata=_doc("reads per second (the chip fuses at 100)"))

    def __post_init__(self) -> None:
        _check_address("address", self.address)
        # A BNO055 answers at these two only. Any other (`address = 28`, decimal: 0x1c) would
        # be taken at start for a dead IMU, and the controller would run without attitude.
        _require(
            self.sensor is not ImuKind.BNO055 or self.address in _BNO055_ADDRESSES,
            "address must be a BNO055's, 0x28 (ADR low) or 0x29 (ADR high), got "
            f"{self.address:#04x} ({self.address}); {_DECIMAL_HINT}",
        )
        _require(-1 <= self.bus <= 255, f"bus must be 0–255 or -1, got {self.bus}")
        _require(
            self.placement in PLACEMENTS,
            f"placement must be one of {', '.join(PLACEMENTS)}, got {self.placement!r}",
        )
        _require(
            math.isfinite(self.heading_offset_deg) and -360 <= self.heading_offset_deg <= 360,
            f"heading_offset_deg must be −360…360, got {self.heading_offset_deg}",
        )
        _require(
            math.isfinite(self.poll_hz) and 1 <= self.poll_hz <= 100,
            f"poll_hz must be 1–100, got {self.poll_hz}",
        )


@dataclass(frozen=True, slots=True)
class LeakConfig:
    """``[leak]``: the leak probe's GPIO input (the action is [controller] leak_action)."""

    pin: int = field(default=-1, metadata=_doc("BCM GPIO number; -1: no leak probe"))
    active_high: bool = field(
        default=True, metadata=_doc("true if the probe drives the pin high when wet")
    )
    pull: str = field(
        default="down",
        metadata=_doc("`down`, `up` or `none` (an external resistor); must suit active_high"),
    )

    def __post_init__(self) -> None:
        _require(-1 <= self.pin <= 53, f"pin must be a BCM GPIO 0–53 or -1, got {self.pin}")
        _require(
            self.pull in ("down", "up", "none"),
            f"pull must be down, up or none, got {self.pull!r}",
        )
        _require(
            self.pull == "none" or (self.pull == "down") == self.active_high,
            f"pull = {self.pull!r} makes the pin rest "
            f"{'low' if self.pull == 'down' else 'high'}: it cannot be active "
            f"{'high' if self.active_high else 'low'}",
        )


#: The default of ``[board] stale_after_s``: five failed reads in a row at the default 100 Hz
#: (the first to the fifth, four control periods apart), as the limit counted in reads was.
STALE_AFTER_S = 0.04
#: The longest it may be: a dead pressure sensor must not drive on for long.
MAX_STALE_AFTER_S = 10.0


@dataclass(frozen=True, slots=True)
class BoardConfig:
    """``[board]``: the board loop."""

    stale_after_s: float = field(
        default=STALE_AFTER_S,
        metadata=_doc(
            "a sensor whose reads have been failing this long (a read fails this long after the "
            "first failed one, no good reading between) is stale, whatever tick_hz: the "
            "pressure sensor's stops the motors (stale-sensor failsafe; they may be started "
            "again once it answers), the IMU's is reported and driving goes on; "
            f"0–{MAX_STALE_AFTER_S:g} s (0: at the first failed read)"
        ),
    )
    overrun_warning_s: float = field(
        default=10.0, metadata=_doc("log control-loop overruns at most this often, s")
    )

    def __post_init__(self) -> None:
        _require(
            math.isfinite(self.stale_after_s) and 0 <= self.stale_after_s <= MAX_STALE_AFTER_S,
            f"stale_after_s must be 0–{MAX_STALE_AFTER_S:g} s, got {self.stale_after_s}",
        )
        _require(
            math.isfinite(self.overrun_warning_s) and self.overrun_warning_s > 0,
            f"overrun_warning_s must be > 0, got {self.overrun_warning_s}",
        )


@dataclass(frozen=True, slots=True)
class PiConfig:
    """A whole ``rov.toml``: the controller and the board it runs on."""

    controller: ControllerConfig
    escs: tuple[EscConfig, ...]  # in the order of controller.thrusters
    i2c: I2cConfig = field(default_factory=I2cConfig)
    #: The PWM boards on the bus: ``[pca9685]``, or several as ``[[pca9685]]``.
    pwm_boards: tuple[Pca9685Config, ...] = (Pca9685Config(),)
    claw: ClawConfig = field(default_factory=ClawConfig)
    pressure: PressureConfig = field(default_factory=PressureConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    leak: LeakConfig = field(default_factory=LeakConfig)
    board: BoardConfig = field(default_factory=BoardConfig)

    def __post_init__(self) -> None:
        if not self.pwm_boards:
            raise ConfigError("at least one PCA9685 is needed")

    def pwm_board_index(self, pca9685: int) -> int:
        """The place in :attr:`pwm_boards` of an output's ``pca9685`` key (-1: the first);
        :class:`ConfigError` if no PWM board is at that address."""
        if pca9685 == -1:
            return 0
        for index, board in enumerate(self.pwm_boards):
            if board.address == pca9685:
                return index
        addresses = ", ".join(f"{board.address:#04x}" for board in self.pwm_boards)
        raise ConfigError(f"no PCA9685 at {pca9685:#04x}; the PWM boards are at {addresses}")

    def pwm_board_table(self, index: int) -> str:
        """How the file names the PWM board at ``index``: ``[pca9685]`` or ``[[pca9685]] #N``."""
        return "[pca9685]" if len(self.pwm_boards) == 1 else f"[[pca9685]] #{index + 1}"


#: The board's tables, beside the controller's.
_BOARD_TABLES = ("i2c", "pca9685", "esc", "claw", "pressure", "imu", "leak", "board")


def _table(data: Mapping[str, Any], name: str, where: str) -> Mapping[str, Any]:
    table = data.get(name, {})
    if not isinstance(table, Mapping):
        raise ConfigError(f"{where} must be a table, got {type(table).__name__}")
    return table


def pi_config_from_mapping(data: Mapping[str, Any], source: str = "rov.toml") -> PiConfig:
    """The configuration in parsed TOML ``data``; :class:`ConfigError` names what is wrong."""
    controller = config_from_mapping(data, source, other_tables=_BOARD_TABLES)
    escs, i2c, pwm_boards, claw = _output_tables(data, controller, source)
    pressure_table = dict(_table(data, "pressure", f"{source} [pressure]"))
    ms5837 = dataclass_from_table(
        Ms5837Config,
        _table(pressure_table, "ms5837", f"{source} [pressure.ms5837]"),
        f"{source} [pressure.ms5837]",
    )
    ads1115 = dataclass_from_table(
        Ads1115Config,
        _table(pressure_table, "ads1115", f"{source} [pressure.ads1115]"),
        f"{source} [pressure.ads1115]",
    )
    pressure_table.pop("ms5837", None)
    pressure_table.pop("ads1115", None)
    pressure = dataclass_from_table(
        PressureConfig, pressure_table, f"{source} [pressure]", ms5837=ms5837, ads1115=ads1115
    )
    imu = dataclass_from_table(ImuConfig, _table(data, "imu", f"{source} [imu]"), f"{source} [imu]")
    leak = dataclass_from_table(
        LeakConfig, _table(data, "leak", f"{source} [leak]"), f"{source} [leak]"
    )
    board = dataclass_from_table(
        BoardConfig, _table(data, "board", f"{source} [board]"), f"{source} [board]"
    )
    config = PiConfig(controller, escs, i2c, pwm_boards, claw, pressure, imu, leak, board)
    _check_addresses(config, source)  # (first: an output's pca9685 key names an address)
    _check_outputs(config, source)
    _check_depth_scale(config, source)
    _check_watchdog(config, source)
    _check_leak_pin(config, source)
    return config


#: A Raspberry Pi's GPIOs that are I²C bus 1's lines.
_I2C_BUS_1_LINES = {2: "SDA", 3: "SCL"}


def _check_leak_pin(config: PiConfig, source: str) -> None:
    """No leak probe on a line of the I²C bus the board uses: claimed as an input, the pin is
    taken from the bus (every device on it stops answering, the PWM board included), and
    what is left of the bus's traffic reads as leaks. gpiozero refuses a pull-down there
    (the lines' pull-ups are fixed), not the pull-up of an active-low probe."""
    line = _I2C_BUS_1_LINES.get(config.leak.pin)
    buses = {config.i2c.bus}
    if config.imu.sensor is ImuKind.BNO055 and config.imu.bus != -1:
        buses.add(config.imu.bus)
    if line is None or 1 not in buses:
        return
    raise ConfigError(
        f"{source} [leak] pin: GPIO {config.leak.pin} is {line} of I²C bus 1, which the "
        "board's devices are on: read as a leak probe it would be taken from the bus; wire "
        "the probe to a free GPIO (27 in docs/hardware.md's wiring)"
    )


def load_pi_config(path: Path | str) -> PiConfig:
    """Read and check a ``rov.toml``."""
    return pi_config_from_mapping(read_toml(path), str(path))


#: The tables that say which pulses the PWM boards make: all that setting neutral needs.
_OUTPUT_TABLES = ("thrusters", "i2c", "pca9685", "esc", "claw")


def load_pi_outputs_config(path: Path | str) -> PiConfig:
    """The PWM boards' part of a ``rov.toml``: its ``[[thrusters]]``, ``[i2c]``, ``[pca9685]``,
    ``[esc.*]`` and ``[claw]``, checked as :func:`load_pi_config` checks them; every other
    table is left unread, at its defaults.

    For setting the thrusters to neutral after the controller died (``--neutral``, systemd's
    ExecStopPost): a mistake elsewhere in the file (an edit made while the controller ran, a
    key a newer version refuses) must not leave the thrusters running.
    """
    data = read_toml(path)
    source = str(path)
    outputs = {name: data[name] for name in _OUTPUT_TABLES if name in data}
    controller = config_from_mapping(outputs, source, other_tables=_BOARD_TABLES)
    config = PiConfig(controller, *_output_tables(outputs, controller, source))
    _check_addresses(config, source, sensors=False)
    _check_outputs(config, source)
    return config


def _output_tables(
    data: Mapping[str, Any], controller: ControllerConfig, source: str
) -> tuple[tuple[EscConfig, ...], I2cConfig, tuple[Pca9685Config, ...], ClawConfig]:
    """The ``[esc.*]``, ``[i2c]``, ``[pca9685]`` and ``[claw]`` tables of ``data``, in
    :class:`PiConfig`'s order."""
    escs = _escs(controller, _table(data, "esc", f"{source} [esc]"), source)
    i2c = dataclass_from_table(I2cConfig, _table(data, "i2c", f"{source} [i2c]"), f"{source} [i2c]")
    claw = dataclass_from_table(
        ClawConfig, _table(data, "claw", f"{source} [claw]"), f"{source} [claw]"
    )
    return escs, i2c, _pwm_boards(data, source), claw


def _check_outputs(config: PiConfig, source: str) -> None:
    """Each output on a PWM board of the file, on a channel of its own, its pulses in the
    board's period."""
    _check_pwm_board_keys(config, source)
    _check_channels(config, source)
    _check_pulses_fit(config, source)


def _pwm_boards(data: Mapping[str, Any], source: str) -> tuple[Pca9685Config, ...]:
    """``[pca9685]`` (one PWM board), or ``[[pca9685]]`` (one table for each)."""
    tables = data.get("pca9685", {})
    if not isinstance(tables, list):
        where = f"{source} [pca9685]"
        return (dataclass_from_table(Pca9685Config, _table(data, "pca9685", where), where),)
    if not tables:
        raise ConfigError(f"{source} [[pca9685]]: no PWM board; one table for each PCA9685")
    return tuple(
        dataclass_from_table(Pca9685Config, table, f"{source} [[pca9685]] #{index + 1}")
        for index, table in enumerate(tables)
    )


def _outputs(config: PiConfig) -> list[tuple[str, int, int]]:
    """Every output in use: its table, its PWM board's place in ``pwm_boards``, its channel."""
    outputs = [
        (f"[esc.{thruster.name}]", config.pwm_board_index(esc.pca9685), esc.channel)
        for esc, thruster in zip(config.escs, config.controller.thrusters, strict=True)
    ]
    if config.claw.kind is not ClawKind.NONE:
        claw = config.claw
        outputs.append(("[claw]", config.pwm_board_index(claw.pca9685), claw.channel))
    return outputs


def _check_pwm_board_keys(config: PiConfig, source: str) -> None:
    """Every output's ``pca9685`` names a PWM board of the file."""
    tables = [
        (f"[esc.{thruster.name}]", esc.pca9685)
        for esc, thruster in zip(config.escs, config.controller.thrusters, strict=True)
    ]
    if config.claw.kind is not ClawKind.NONE:
        tables.append(("[claw]", config.claw.pca9685))
    for table, pca9685 in tables:
        try:
            config.pwm_board_index(pca9685)
        except ConfigError as error:
            raise ConfigError(f"{source} {table} pca9685: {error}") from None


def _escs(
    controller: ControllerConfig, tables: Mapping[str, Any], source: str
) -> tuple[EscConfig, ...]:
    names = [thruster.name for thruster in controller.thrusters]
    unknown = sorted(set(tables) - set(names))
    if unknown:
        raise ConfigError(
            f"{source} [esc.{unknown[0]}]: no thruster of that name in the layout; "
            f"the thrusters are: {', '.join(names)}"
        )
    missing = [name for name in names if name not in tables]
    if missing:
        raise ConfigError(
            f"{source} [esc]: thruster {missing[0]!r} has no ESC output; add [esc.{missing[0]}] "
            "with its channel"
        )
    escs = []
    for name in names:
        where = f"{source} [esc.{name}]"
        table = _table(tables, name, where)
        if "channel" not in table:
            raise ConfigError(f"{where}: channel is required")
        escs.append(dataclass_from_table(EscConfig, table, where))
    return tuple(escs)


def _check_channels(config: PiConfig, source: str) -> None:
    users: dict[tuple[int, int], str] = {}
    several = len(config.pwm_boards) > 1
    for user, board, channel in _outputs(config):
        if (board, channel) in users:
            on = f" of the PCA9685 at {config.pwm_boards[board].address:#04x}" if several else ""
            raise ConfigError(
                f"{source} {user} channel: {channel}{on} is already used by {users[board, channel]}"
            )
        users[board, channel] = user


def _check_addresses(config: PiConfig, source: str, *, sensors: bool = True) -> None:
    """No two devices at one address on one bus: one's writes would reach the other (an
    ADS1115's config word lands in a PCA9685's MODE2 and makes its outputs open-drain).
    ``sensors``: the sensors' addresses too, not only the PWM boards'."""
    pressure = config.pressure
    devices = [
        (config.pwm_board_table(index), board.address)
        for index, board in enumerate(config.pwm_boards)
    ]
    if sensors:
        if pressure.sensor is PressureKind.MS5837:
            devices.append(("[pressure.ms5837]", pressure.ms5837.address))
        else:
            devices.append(("[pressure.ads1115]", pressure.ads1115.address))
        if config.imu.sensor is ImuKind.BNO055 and config.imu.bus in (-1, config.i2c.bus):
            devices.append(("[imu]", config.imu.address))
    users: dict[int, str] = {}
    for user, address in devices:
        if address in users:
            # The usual slip: 40 for the 0x40 that i2cdetect shows.
            raise ConfigError(
                f"{source} {user} address: {address:#04x} ({address}) is already used by "
                f"{users[address]} on I²C bus {config.i2c.bus}; a TOML number is decimal "
                "unless written 0x…"
            )
        users[address] = user


def _check_pulses_fit(config: PiConfig, source: str) -> None:
    """Each PWM board's period holds the longest pulse of the outputs on it."""
    longest_us = [0.0] * len(config.pwm_boards)
    for esc in config.escs:
        board = config.pwm_board_index(esc.pca9685)
        longest_us[board] = max(longest_us[board], esc.max_us)
    claw = config.claw
    if claw.kind is not ClawKind.NONE:
        board = config.pwm_board_index(claw.pca9685)
        longest_us[board] = max(longest_us[board], claw.open_us, claw.close_us, claw.neutral_us)
    for index, (pwm, longest) in enumerate(zip(config.pwm_boards, longest_us, strict=True)):
        prescale = prescale_for(pwm.frequency_hz, pwm.oscillator_hz)
        period_us = 4096 * (prescale + 1) / pwm.oscillator_hz * 1e6
        _require(
            longest < period_us,
            f"{source} {config.pwm_board_table(index)} frequency_hz: a {longest:g} µs pulse "
            f"does not fit in the {period_us:.0f} µs period of {pwm.frequency_hz:g} Hz",
        )


def _check_depth_scale(config: PiConfig, source: str) -> None:
    """The board maps pressure onto raw counts of k / 100 cm: k = 0, which the controller's
    [depth] and `sdk` accept, gives it no scale to map onto."""
    k = config.controller.depth.k
    _require(
        k >= MIN_SCALE_K,
        f"{source} [depth]: k must be in {MIN_SCALE_K}–10000 on a Pi board "
        f"(a raw count is k / 100 cm of water), got {k}",
    )


def _check_watchdog(config: PiConfig, source: str) -> None:
    """The link-loss failsafe is what stops a robot whose link died: never off, never hours."""
    problem = board_watchdog_problem(config.controller.watchdog_s)
    _require(problem is None, f"{source} [controller] watchdog_s: {problem}")


def pi_config_reference() -> str:
    """Markdown tables of every board key with its default and meaning."""
    return "\n".join(
        [
            table_reference("[i2c]", I2cConfig()),
            table_reference("[pca9685]", Pca9685Config()),
            table_reference("[esc.<thruster name>]", EscConfig(channel=0)),
            table_reference("[claw]", ClawConfig()),
            table_reference("[pressure]", PressureConfig()),
            table_reference("[pressure.ms5837]", Ms5837Config()),
            table_reference("[pressure.ads1115]", Ads1115Config()),
            table_reference("[imu]", ImuConfig()),
            table_reference("[leak]", LeakConfig()),
            table_reference("[board]", BoardConfig()),
        ]
    )
