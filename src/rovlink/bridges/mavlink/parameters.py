"""The parameter table a ground station reads and writes (the MAVLink parameter protocol).

Each controller parameter is one argument of one command of the table: its range comes from
there, and setting it sends that command. The protocol cannot read a setting back, so a value is
the one last sent (at start: the controller's configured reset default, or the value from a
parameter file, which is then sent). ``SYSID_MYGCS`` and ``BTNn_FUNCTION`` are the bridge's own:
the ground station that flies the vehicle, as ArduSub's, and which ArduSub joystick function each
button of MANUAL_CONTROL carries out.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from rovlink.bridges.mavlink.modes import SUPPORTED_BUTTON_FUNCTIONS, ButtonFunction
from rovlink.protocol import Command, lookup

__all__ = [
    "BUTTON_COUNT",
    "DEFAULT_BUTTON_FUNCTIONS",
    "DEFAULT_PILOT_SYSTEM",
    "PILOT_SYSTEM",
    "Parameter",
    "ParameterError",
    "ParameterTable",
    "button_parameter",
    "number_text",
    "read_parameter_file",
]

#: MANUAL_CONTROL carries 32 buttons (``buttons`` 0–15, the extension ``buttons2`` 16–31), as
#: ArduSub's BTN0…BTN31_FUNCTION.
BUTTON_COUNT = 32
#: ArduSub's defaults for the buttons whose functions the bridge can carry out.
DEFAULT_BUTTON_FUNCTIONS: Mapping[int, ButtonFunction] = {
    1: ButtonFunction.MODE_MANUAL,
    2: ButtonFunction.MODE_DEPTH_HOLD,
    4: ButtonFunction.DISARM,
    6: ButtonFunction.ARM,
}
#: ArduSub's parameter naming the ground station whose joystick and heartbeat count.
PILOT_SYSTEM = "SYSID_MYGCS"
#: Its default, ArduSub's: the system id that QGroundControl, MAVProxy and pymavlink use.
DEFAULT_PILOT_SYSTEM = 255


#: Whole numbers below this are written in full; beyond it a float's digits are not all exact.
_EXACT_INTEGER_LIMIT = 2**53
_MOST_DIGITS = 17  # enough for any double


def _as_float32(value: float) -> float | None:
    """``value`` rounded to a float32 (PARAM_SET's type), or ``None`` beyond its range."""
    try:
        return float(struct.unpack("<f", struct.pack("<f", value))[0])
    except OverflowError:
        return None


def number_text(value: float) -> str:
    """A refused value, whole and short: what the ground station typed, never a cut.

    A float32 from PARAM_SET is written with the fewest digits that give it back, as typed.

    >>> number_text(120.0), number_text(1.5), number_text(float("nan")), number_text(-1e400)
    ('120', '1.5', 'nan', '-inf')
    >>> number_text(_as_float32(1e30)), number_text(_as_float32(0.1)), number_text(1e30)
    ('1e+30', '0.1', '1e+30')
    """
    if not math.isfinite(value):
        return str(value)
    if value == round(value) and abs(value) < _EXACT_INTEGER_LIMIT:
        return str(int(value))
    single = _as_float32(value) == value
    for digits in range(1, _MOST_DIGITS + 1):
        text = f"{value:.{digits}g}"
        parsed = float(text)
        if parsed == value or (single and _as_float32(parsed) == value):
            return text
    return repr(value)  # (not reached: 17 digits give any double back)


class ParameterError(ValueError):
    """A parameter name or value the table refuses; the message names both."""


@dataclass(frozen=True, slots=True)
class Parameter:
    """One parameter: its MAVLink name, what it is, its range and the command that sets it."""

    name: str
    description: str
    minimum: int
    maximum: int
    #: The command whose only argument this parameter is; ``None``: the bridge's own setting.
    command_name: str | None = None

    def command(self, value: int) -> Command | None:
        """The command that puts ``value`` into effect on the controller, if any."""
        return None if self.command_name is None else Command(self.command_name, (value,))


def _from_command(name: str, command_name: str, description: str) -> Parameter:
    (argument,) = lookup(command_name).arguments
    return Parameter(name, description, argument.minimum, argument.maximum, command_name)


def button_parameter(button: int) -> str:
    """The parameter name of a button's function.

    >>> button_parameter(3)
    'BTN3_FUNCTION'
    """
    return f"BTN{button}_FUNCTION"


_CONTROLLER_PARAMETERS = (
    _from_command("RL_DEPTH_P", "mvpdp", "depth PID proportional gain"),
    _from_command("RL_DEPTH_I", "mvpdi", "depth PID integral gain"),
    _from_command("RL_DEPTH_D", "mvpidd", "depth PID derivative gain"),
    _from_command("RL_MAX_PWM", "mgmp", "PWM duty cap of every thruster"),
    _from_command("RL_DEPTH_ZERO", "sdz", "raw pressure reading at the surface"),
    _from_command("RL_DEPTH_K", "sdk", "depth coefficient: depth[m] = (raw − zero) · k / 10000"),
)
_PILOT_PARAMETER = Parameter(
    PILOT_SYSTEM,
    "the ground station that flies the vehicle: only its MANUAL_CONTROL and HEARTBEAT count",
    1,
    255,
)
_BUTTON_PARAMETERS = tuple(
    Parameter(
        button_parameter(button),
        f"ArduSub joystick function of button {button}",
        0,
        max(SUPPORTED_BUTTON_FUNCTIONS),
    )
    for button in range(BUTTON_COUNT)
)


class ParameterTable:
    """The parameters in a fixed order (a ground station asks by index too) and their values.

    >>> table = ParameterTable({"RL_DEPTH_P": 40})
    >>> table.value("RL_DEPTH_P")
    40
    >>> str(table.set("RL_DEPTH_P", 35.0))
    '#mvpdp.35!'
    >>> try:
    ...     table.set("RL_DEPTH_P", 120)
    ... except ParameterError as error:
    ...     print(error)
    RL_DEPTH_P must be an integer in 0–99, got 120
    """

    def __init__(self, values: Mapping[str, int] | None = None) -> None:
        self.parameters: tuple[Parameter, ...] = (
            *_CONTROLLER_PARAMETERS,
            _PILOT_PARAMETER,
            *_BUTTON_PARAMETERS,
        )
        self._by_name = {parameter.name: parameter for parameter in self.parameters}
        self._values: dict[str, int] = {parameter.name: 0 for parameter in self.parameters}
        self._values[PILOT_SYSTEM] = DEFAULT_PILOT_SYSTEM
        for button, function in DEFAULT_BUTTON_FUNCTIONS.items():
            self._values[button_parameter(button)] = int(function)
        for name, value in (values or {}).items():
            self._values[name] = self._checked(name, value)

    def __len__(self) -> int:
        return len(self.parameters)

    def names(self) -> list[str]:
        """Every parameter name, in index order."""
        return [parameter.name for parameter in self.parameters]

    def index(self, name: str) -> int:
        """The index of ``name`` (``ParameterError`` if there is no such parameter)."""
        return self.parameters.index(self.parameter(name))

    def parameter(self, name: str) -> Parameter:
        """The parameter called ``name``."""
        try:
            return self._by_name[name]
        except KeyError:
            raise ParameterError(f"no parameter {name!r}") from None

    def value(self, name: str) -> int:
        """The value of ``name`` as last set."""
        self.parameter(name)
        return self._values[name]

    def items(self) -> Iterable[tuple[str, int]]:
        """``(name, value)`` in index order."""
        return ((parameter.name, self._values[parameter.name]) for parameter in self.parameters)

    @property
    def pilot_system(self) -> int:
        """The system id of the ground station that flies the vehicle (``SYSID_MYGCS``)."""
        return self._values[PILOT_SYSTEM]

    def button_function(self, button: int) -> ButtonFunction:
        """The function button ``button`` carries out."""
        return ButtonFunction(self._values[button_parameter(button)])

    def disarm_button_assigned(self) -> bool:
        """Whether a button disarms (``DISARM`` or ``ARM_TOGGLE``): ArduSub's pre-arm check,
        since underwater the pilot's hands are on the joystick."""
        disarming = {ButtonFunction.DISARM, ButtonFunction.ARM_TOGGLE}
        return any(self.button_function(button) in disarming for button in range(BUTTON_COUNT))

    def set(self, name: str, value: float) -> Command | None:
        """Set ``name`` to ``value``; the command to send for it (``None``: the bridge's own).

        Nothing changes when the value is refused (``ParameterError`` says why).
        """
        checked = self._checked(name, value)
        self._values[name] = checked
        return self.parameter(name).command(checked)

    def commands(self, names: Iterable[str]) -> list[Command]:
        """The commands that put the values of ``names`` into effect, in table order (the
        bridge's own parameters need none)."""
        wanted = set(names)
        for name in wanted:
            self.parameter(name)  # ParameterError for a name not in the table
        commands = []
        for name, value in self.items():
            command = self._by_name[name].command(value) if name in wanted else None
            if command is not None:
                commands.append(command)
        return commands

    def _checked(self, name: str, value: float) -> int:
        parameter = self.parameter(name)
        range_text = f"{parameter.minimum}–{parameter.maximum}"
        if (
            not math.isfinite(value)
            or value != round(value)
            or not parameter.minimum <= value <= parameter.maximum
        ):
            shown = number_text(value)
            raise ParameterError(f"{name} must be an integer in {range_text}, got {shown}")
        integer = round(value)
        if name.startswith("BTN") and integer not in SUPPORTED_BUTTON_FUNCTIONS:
            supported = ", ".join(f"{int(f)} {f.name.lower()}" for f in ButtonFunction)
            raise ParameterError(f"{name}: function {integer} is not supported; use {supported}")
        return integer


#: QGroundControl's columns: vehicle id, component id, name, value, MAV_PARAM_TYPE.
_QGC_COLUMNS = 5
_AUTOPILOT_COMPONENT = 1
_PARAM_TYPES = range(1, 11)  # MAV_PARAM_TYPE_UINT8 … MAV_PARAM_TYPE_REAL64
_FORMS = (
    "expected NAME VALUE (MAVProxy, Mission Planner: NAME,VALUE) or "
    "VEHICLE COMPONENT NAME VALUE TYPE (QGroundControl)"
)


def read_parameter_file(text: str, source: str) -> dict[str, int]:
    """Parameters from a ground station's parameter file, in the forms they save:

    - MAVProxy ``NAME VALUE`` (Mission Planner ``NAME,VALUE``) per line;
    - QGroundControl ``VEHICLE<TAB>COMPONENT<TAB>NAME<TAB>VALUE<TAB>TYPE`` per line, the
      autopilot's (component 1) parameters.

    ``#`` starts a comment. Errors name the file and line; every value is checked.

    >>> read_parameter_file("# QGroundControl\\n1\\t1\\tRL_DEPTH_P\\t33\\t6", "q.params")
    {'RL_DEPTH_P': 33}
    """
    table = ParameterTable()
    values: dict[str, int] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        content = line.split("#", 1)[0].strip()
        if not content:
            continue
        try:
            name, value = _name_and_value(content)
            table.set(name, value)
        except ParameterError as error:
            raise ParameterError(f"{source}:{number}: {error}") from None
        values[name] = table.value(name)
    return values


def _name_and_value(content: str) -> tuple[str, float]:
    """The name and value of one line of a parameter file, in either form."""
    fields = content.replace(",", " ").split()
    if len(fields) == _QGC_COLUMNS:
        vehicle, component, name, text_value, param_type = fields
        _check_column("vehicle id", vehicle, range(1, 256))
        _check_column("component id", component, range(_AUTOPILOT_COMPONENT, 2))
        _check_column("type", param_type, _PARAM_TYPES)
    elif len(fields) == 2:
        name, text_value = fields
    else:
        raise ParameterError(f"{_FORMS}, got {content!r}")
    try:
        return name, float(text_value)
    except ValueError:
        raise ParameterError(f"{name}: not a number: {text_value!r}") from None


def _check_column(label: str, text: str, allowed: range) -> None:
    if not text.isdigit() or int(text) not in allowed:
        expected = (
            f"{allowed.start} (the autopilot's: the bridge has no other)"
            if label == "component id"
            else f"an integer in {allowed.start}–{allowed.stop - 1}"
        )
        raise ParameterError(f"{label} must be {expected}, got {text!r}")
