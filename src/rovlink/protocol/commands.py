"""The command table: the single definition of every frame of the protocol (PROTOCOL.md Part 1).

Everything else — the encoder, the decoder, the controller's dispatch, the host driver's methods,
console completion and help, and ``docs/commands.md`` — is derived from :data:`COMMANDS` and
:data:`RESPONSES`. A new command is one new entry here plus its behaviour in the controller.
"""

from __future__ import annotations

from rovlink.protocol.frozen import frozen
from rovlink.protocol.text_enum import StrEnum

__all__ = [
    "COMMANDS",
    "RESPONSES",
    "SPELLINGS",
    "Argument",
    "Kind",
    "Setting",
    "Spec",
    "UnknownCommandError",
    "VerticalMode",
    "lookup",
]


class Kind(StrEnum):
    """Direction of a frame: host → controller commands start with ``#``, replies with ``$``."""

    COMMAND = "command"
    RESPONSE = "response"

    @property
    def start_byte(self) -> bytes:
        """The frame's start character."""
        return b"#" if self is Kind.COMMAND else b"$"


class VerticalMode(StrEnum):
    """The vertical control mode a command needs (P9)."""

    DIRECT = "direct"
    DEPTH = "depth"


class Setting(StrEnum):
    """An on/off state of the controller that commands switch (a toggle pair, or one frame's 0/1).

    Each command's :attr:`Spec.setting` and :attr:`Spec.setting_value` say which state it switches
    and to what, so that the controller, the client and the tools read the pairs from one place.
    """

    CHECKSUM = "checksum"  # crcon / crcoff (P3)
    DEBUG = "debug"  # debug1 / debug0 (P5)
    LOCKED = "locked"  # stop / start (P7)
    DIRECT_MODE = "direct_mode"  # mvdirect.1 / mvdirect.0 (P9)
    CLAW_OPEN = "claw_open"  # h+ / h- (P16): the direction of the claw's next pulse


@frozen
class Argument:
    """One decimal integer argument of a frame (P6)."""

    __slots__ = ("description", "maximum", "minimum", "name", "signed", "unit")
    __match_args__ = ("name", "minimum", "maximum", "signed", "description", "unit")

    name: str
    minimum: int
    maximum: int
    signed: bool
    description: str
    #: The unit people write after the value (``cm``, ``%``, ``°``), empty for a plain number.
    unit: str

    def __init__(  # noqa: PLR0917 - positional, as the table writes arguments
        self,
        name: str,
        minimum: int,
        maximum: int,
        signed: bool = False,
        description: str = "",
        unit: str = "",
    ) -> None:
        _set = object.__setattr__
        _set(self, "name", name)
        _set(self, "minimum", minimum)
        _set(self, "maximum", maximum)
        _set(self, "signed", signed)
        _set(self, "description", description)
        _set(self, "unit", unit)

    def check(self, value: int) -> bool:
        """Whether ``value`` is in range (P6: out of range is dropped, never clamped).

        >>> Argument("power_percent", 0, 100).check(101)
        False
        """
        return self.minimum <= value <= self.maximum

    def range_text(self) -> str:
        """The range as people write it: ``0–255``, or for a signed argument with its signs
        (ASCII, as in a frame).

        >>> Argument("thrust_percent", -100, 100, signed=True).range_text()
        '-100…+100'
        """
        if self.signed:
            return f"{self.minimum:+d}…{self.maximum:+d}"
        return f"{self.minimum}–{self.maximum}"

    def format(self, value: int) -> str:
        """The value as the controller writes it: no leading zeros, a sign if signed (P6)."""
        return f"{value:+d}" if self.signed else str(value)


@frozen
class Spec:
    """Everything the project knows about one frame name."""

    __slots__ = (
        "aliases",
        "arguments",
        "description",
        "exact_match",
        "honoured_bare",
        "kind",
        "mode",
        "motion",
        "name",
        "replies",
        "rules",
        "setting",
        "setting_value",
    )
    __match_args__ = (
        "name",
        "kind",
        "description",
        "arguments",
        "rules",
        "aliases",
        "exact_match",
        "honoured_bare",
        "motion",
        "mode",
        "replies",
        "setting",
        "setting_value",
    )

    name: str
    kind: Kind
    description: str
    arguments: tuple[Argument, ...]
    rules: tuple[str, ...]
    aliases: tuple[str, ...]
    #: Recognised by exact match before any checksum is stripped and never carries one (P3).
    exact_match: bool
    #: Honoured without a checksum even in checksum mode (P3): it can only make the robot safer,
    #: so a host sends it bare, and it works whatever mode the controller is in.
    honoured_bare: bool
    #: Dropped while the motors are locked (P7).
    motion: bool
    #: The vertical mode the command needs, if any (P9).
    mode: VerticalMode | None
    #: For a query: the names of the responses it produces, in order (P4, P12).
    replies: tuple[str, ...]
    #: The on/off state the command switches, if any, and the value it sets (``None``: the value
    #: is the command's 0/1 argument, as in ``mvdirect``).
    setting: Setting | None
    setting_value: bool | None

    def __init__(  # noqa: PLR0917 - positional, as the table writes its specs
        self,
        name: str,
        kind: Kind,
        description: str,
        arguments: tuple[Argument, ...] = (),
        rules: tuple[str, ...] = (),
        aliases: tuple[str, ...] = (),
        exact_match: bool = False,
        honoured_bare: bool = False,
        motion: bool = False,
        mode: VerticalMode | None = None,
        replies: tuple[str, ...] = (),
        setting: Setting | None = None,
        setting_value: bool | None = None,
    ) -> None:
        _set = object.__setattr__
        _set(self, "name", name)
        _set(self, "kind", kind)
        _set(self, "description", description)
        _set(self, "arguments", arguments)
        _set(self, "rules", rules)
        _set(self, "aliases", aliases)
        _set(self, "exact_match", exact_match)
        _set(self, "honoured_bare", honoured_bare)
        _set(self, "motion", motion)
        _set(self, "mode", mode)
        _set(self, "replies", replies)
        _set(self, "setting", setting)
        _set(self, "setting_value", setting_value)

    @property
    def is_query(self) -> bool:
        """Whether the command asks for a reply."""
        return bool(self.replies)

    @property
    def moves_or_unlocks(self) -> bool:
        """Whether the command moves the robot or unlocks its motors (P7): what must not go out
        after a ``#stop!`` asked for after it, as it would undo the stop.

        >>> [lookup(name).moves_or_unlocks for name in ("start", "th", "h+", "mvdirect", "qd")]
        [True, True, True, False, False]
        """
        return self.motion or (self.setting is Setting.LOCKED and self.setting_value is False)

    def template(self) -> str:
        """The frame with argument placeholders, e.g. ``#th.<direction_deg>.<power_percent>!``."""
        parts = [self.name, *(f"<{argument.name}>" for argument in self.arguments)]
        return self.kind.start_byte.decode() + ".".join(parts) + "!"

    def body(self, values: tuple[int, ...]) -> str:
        """The frame body (no start, checksum or end) for already validated values."""
        if not values:
            return self.name
        formatted = (arg.format(value) for arg, value in zip(self.arguments, values, strict=True))
        return self.name + "." + ".".join(formatted)


def _arg(
    name: str,
    minimum: int,
    maximum: int,
    description: str,
    *,
    signed: bool = False,
    unit: str = "",
) -> Argument:
    return Argument(name, minimum, maximum, signed, description, unit)


_C = Kind.COMMAND
_R = Kind.RESPONSE

_DEPTH_CM = _arg("depth_cm", 0, 9999, "depth below the surface, cm", unit="cm")
_RAW = _arg("raw", 0, 1024, "raw pressure-sensor reading")
_GAIN = _arg("gain", 0, 99, "PID gain, scaled by the controller's configuration")
_FLAG = _arg("enabled", 0, 1, "1 on, 0 off")
_ROLL = _arg("roll_deg", -90, 90, "roll, degrees, + starboard down", signed=True, unit="°")
_PITCH = _arg("pitch_deg", -90, 90, "pitch, degrees, + bow up", signed=True, unit="°")
_HEADING = _arg("heading_deg", 0, 360, "magnetic heading, degrees", unit="°")
_LEAK = _arg("leak", 0, 1, "1 if the leak sensor fired since the last reset")

_SENSOR_REPLIES = ("qd", "qr", "q.l", "qro", "qpi", "qhe")

COMMANDS: tuple[Spec, ...] = (
    Spec(
        "crcon",
        _C,
        "turn checksum use on (never carries a checksum)",
        rules=("P3",),
        exact_match=True,
        setting=Setting.CHECKSUM,
        setting_value=True,
    ),
    Spec(
        "crcoff",
        _C,
        "turn checksum use off (never carries a checksum)",
        rules=("P3",),
        exact_match=True,
        setting=Setting.CHECKSUM,
        setting_value=False,
    ),
    Spec(
        "stop",
        _C,
        "switch all motors off and lock their control",
        rules=("P3", "P7"),
        honoured_bare=True,
        setting=Setting.LOCKED,
        setting_value=True,
    ),
    Spec(
        "start",
        _C,
        "allow motor control, with neutral set-points",
        rules=("P7",),
        setting=Setting.LOCKED,
        setting_value=False,
    ),
    Spec("debug1", _C, "debug output on", rules=("P5",), setting=Setting.DEBUG, setting_value=True),
    Spec(
        "debug0", _C, "debug output off", rules=("P5",), setting=Setting.DEBUG, setting_value=False
    ),
    Spec(
        "mgmp",
        _C,
        "maximum PWM duty for every thruster",
        rules=("P8",),
        arguments=(_arg("max_pwm", 0, 255, "PWM duty cap"),),
    ),
    Spec("mvpdp", _C, "vertical (depth) PID proportional gain", rules=("P10",), arguments=(_GAIN,)),
    Spec("mvpdi", _C, "vertical (depth) PID integral gain", rules=("P10",), arguments=(_GAIN,)),
    Spec(
        "mvpidd",
        _C,
        "vertical (depth) PID derivative gain",
        rules=("P10", "P18"),
        arguments=(_GAIN,),
        aliases=("mvpdd",),
    ),
    Spec(
        "mvdirect",
        _C,
        "vertical direct-control mode on (1) or depth mode (0)",
        rules=("P9",),
        arguments=(_FLAG,),
        setting=Setting.DIRECT_MODE,
    ),
    Spec(
        "mvs",
        _C,
        "direct mode: vertical thrust, % (+ up, − down)",
        rules=("P6", "P7", "P9"),
        arguments=(
            _arg("thrust_percent", -100, 100, "vertical thrust, + up", signed=True, unit="%"),
        ),
        motion=True,
        mode=VerticalMode.DIRECT,
    ),
    Spec(
        "mvd",
        _C,
        "depth mode: hold this depth, cm from the surface",
        rules=("P7", "P9"),
        arguments=(_arg("target_depth_cm", 0, 9999, "target depth, cm", unit="cm"),),
        motion=True,
        mode=VerticalMode.DEPTH,
    ),
    Spec(
        "th",
        _C,
        "horizontal motion: direction (0 ahead, clockwise) and power",
        rules=("P7", "P11"),
        arguments=(
            _arg("direction_deg", 0, 360, "degrees clockwise from the bow", unit="°"),
            _arg("power_percent", 0, 100, "horizontal power, %", unit="%"),
        ),
        motion=True,
    ),
    Spec("qd", _C, "query depth, cm", rules=("P13",), replies=("qd",)),
    Spec("qr", _C, "query the raw pressure-sensor reading", rules=("P13",), replies=("qr",)),
    Spec(
        "sdz",
        _C,
        "set the depth zero: raw reading at the surface",
        rules=("P13",),
        arguments=(_arg("zero_raw", 0, 1024, "raw reading at the surface"),),
    ),
    Spec(
        "sdk",
        _C,
        "set the depth coefficient k: depth[m] = (raw − zero) · k / 10000",
        rules=("P13",),
        arguments=(_arg("k", 0, 10000, "depth coefficient"),),
    ),
    Spec(
        "q.l",
        _C,
        "query the leak latch (fired since the last reset?)",
        rules=("P14",),
        replies=("q.l",),
    ),
    Spec("slreset", _C, "reset the leak latch", rules=("P14",)),
    Spec("qro", _C, "query roll, degrees", rules=("P15",), replies=("qro",)),
    Spec("qpi", _C, "query pitch, degrees", rules=("P15",), replies=("qpi",)),
    Spec("qhe", _C, "query magnetic heading, degrees", rules=("P15",), replies=("qhe",)),
    Spec(
        "qsa",
        _C,
        "query all sensors: six replies qd, qr, q.l, qro, qpi, qhe",
        rules=("P12",),
        replies=_SENSOR_REPLIES,
    ),
    Spec(
        "h+",
        _C,
        "claw open: run the claw motor for one pulse",
        rules=("P7", "P16"),
        motion=True,
        setting=Setting.CLAW_OPEN,
        setting_value=True,
    ),
    Spec(
        "h-",
        _C,
        "claw close: run the claw motor for one pulse",
        rules=("P7", "P16"),
        motion=True,
        setting=Setting.CLAW_OPEN,
        setting_value=False,
    ),
)

RESPONSES: tuple[Spec, ...] = (
    Spec("qd", _R, "depth, cm", rules=("P13",), arguments=(_DEPTH_CM,)),
    Spec("qr", _R, "raw pressure-sensor reading", rules=("P13",), arguments=(_RAW,)),
    Spec(
        "q.l",
        _R,
        "leak latch: 1 fired since the last reset, 0 not",
        rules=("P14",),
        arguments=(_LEAK,),
    ),
    Spec("qro", _R, "roll, degrees", rules=("P15",), arguments=(_ROLL,)),
    Spec("qpi", _R, "pitch, degrees", rules=("P15",), arguments=(_PITCH,)),
    Spec("qhe", _R, "magnetic heading, degrees", rules=("P15",), arguments=(_HEADING,)),
)

_BY_KIND: dict[Kind, dict[str, Spec]] = {
    Kind.COMMAND: {spec.name: spec for spec in COMMANDS},
    Kind.RESPONSE: {spec.name: spec for spec in RESPONSES},
}
#: Names and aliases as they may appear in a frame, mapped to their spec.
SPELLINGS: dict[Kind, dict[str, Spec]] = {
    kind: {spelling: spec for spec in table.values() for spelling in (spec.name, *spec.aliases)}
    for kind, table in _BY_KIND.items()
}


class UnknownCommandError(ValueError):
    """A name that is not in the command table."""


def lookup(name: str, kind: Kind = Kind.COMMAND) -> Spec:
    """The spec of a command or response by its name or alias.

    >>> lookup("th").arguments[0].name
    'direction_deg'
    >>> lookup("mvpdd").name
    'mvpidd'
    """
    try:
        return SPELLINGS[kind][name]
    except KeyError:
        raise UnknownCommandError(f"unknown {kind.value} {name!r}") from None
