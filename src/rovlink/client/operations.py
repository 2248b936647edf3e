"""What each driver method sends and how it reads the reply — shared by both clients.

The blocking client and the asyncio client are thin: each method validates its arguments here
(before anything is sent), then sends the resulting commands or asks the resulting
:class:`Query`. :mod:`rovlink.client.method_table` ties every method to the frames of the command
table it sends; the tests check that together they cover the whole table.
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

from rovlink.client.errors import InvalidArgumentError
from rovlink.client.sensors import Sensors
from rovlink.protocol import Argument, Command, Response, Setting, lookup, setting_command

__all__ = [
    "DEPTH_CM",
    "HEADING_DEG",
    "LEAK_DETECTED",
    "PITCH_DEG",
    "PRESSURE_RAW",
    "ROLL_DEG",
    "SENSORS",
    "Query",
    "checksum",
    "debug",
    "depth_pid",
    "depth_scale",
    "depth_zero",
    "direct_mode",
    "hold_depth",
    "max_pwm",
    "move",
    "raw_frame",
    "vertical_thrust",
]

T = TypeVar("T")


@dataclass(frozen=True, slots=True)
class Query(Generic[T]):
    """A query and how to turn its replies into the method's result."""

    command: Command
    read: Callable[[Sequence[Response]], T]


def _value(responses: Sequence[Response]) -> int:
    return responses[0].values[0]


def _flag(responses: Sequence[Response]) -> bool:
    return bool(responses[0].values[0])


DEPTH_CM: Query[int] = Query(Command("qd"), _value)
PRESSURE_RAW: Query[int] = Query(Command("qr"), _value)
LEAK_DETECTED: Query[bool] = Query(Command("q.l"), _flag)
ROLL_DEG: Query[int] = Query(Command("qro"), _value)
PITCH_DEG: Query[int] = Query(Command("qpi"), _value)
HEADING_DEG: Query[int] = Query(Command("qhe"), _value)
SENSORS: Query[Sensors] = Query(Command("qsa"), Sensors.from_responses)

STOP = Command("stop")
START = Command("start")
RESET_LEAK = Command("slreset")
CLAW_OPEN = setting_command(Setting.CLAW_OPEN, True)
CLAW_CLOSE = setting_command(Setting.CLAW_OPEN, False)


def _integer(method: str, name: str, value: object, argument: Argument, frame: str) -> int:
    if isinstance(value, bool):
        raise TypeError(f"{method}: {name} must be an integer, got {value!r}")
    if isinstance(value, float):
        if not value.is_integer():
            raise InvalidArgumentError(method, name, value, argument.range_text(), frame)
        number = int(value)
    else:
        try:
            number = operator.index(value)  # type: ignore[arg-type]
        except TypeError:
            raise TypeError(f"{method}: {name} must be an integer, got {value!r}") from None
    if not argument.minimum <= number <= argument.maximum:
        raise InvalidArgumentError(method, name, value, argument.range_text(), frame)
    return number


def _command(method: str, frame: str, **values: object) -> Command:
    """``frame``'s command with the method's arguments, checked against the table's ranges."""
    spec = lookup(frame)
    checked = tuple(
        _integer(method, name, value, argument, frame)
        for (name, value), argument in zip(values.items(), spec.arguments, strict=True)
    )
    return Command(frame, checked)


def _enabled(method: str, enabled: object) -> bool:
    if not isinstance(enabled, bool):
        raise TypeError(f"{method}: enabled must be True or False, got {enabled!r}")
    return enabled


def checksum(enabled: bool) -> Command:
    """``#crcon!`` or ``#crcoff!``.

    >>> str(checksum(True))
    '#crcon!'
    """
    return setting_command(Setting.CHECKSUM, _enabled("set_checksum", enabled))


def debug(enabled: bool) -> Command:
    """``#debug1!`` or ``#debug0!``.

    >>> str(debug(False))
    '#debug0!'
    """
    return setting_command(Setting.DEBUG, _enabled("set_debug", enabled))


def max_pwm(duty: int) -> Command:
    """``#mgmp.N!``, duty 0–255.

    >>> str(max_pwm(200))
    '#mgmp.200!'
    """
    return _command("set_max_pwm", "mgmp", duty=duty)


def depth_pid(
    p: int | None = None,
    i: int | None = None,
    d: int | None = None,
) -> tuple[Command, ...]:
    """The gain commands for each gain given, all checked before any is sent.

    >>> [str(command) for command in depth_pid(p=20, d=5)]
    ['#mvpdp.20!', '#mvpidd.5!']
    """
    gains = (("p", p, "mvpdp"), ("i", i, "mvpdi"), ("d", d, "mvpidd"))
    commands = tuple(
        _command("set_depth_pid", frame, **{name: value})
        for name, value, frame in gains
        if value is not None
    )
    if not commands:
        raise ValueError("set_depth_pid: give at least one of p, i, d (each 0–99)")
    return commands


def direct_mode(enabled: bool) -> Command:
    """``#mvdirect.1!`` (direct vertical thrust) or ``#mvdirect.0!`` (hold depth).

    >>> str(direct_mode(True))
    '#mvdirect.1!'
    """
    return setting_command(Setting.DIRECT_MODE, _enabled("set_direct_mode", enabled))


def vertical_thrust(percent: int) -> Command:
    """``#mvs.±N!``, −100…+100 %, + up.

    >>> str(vertical_thrust(-50))
    '#mvs.-50!'
    """
    return _command("set_vertical_thrust", "mvs", percent=percent)


def hold_depth(depth_cm: int) -> Command:
    """``#mvd.N!``, 0–9999 cm.

    >>> str(hold_depth(100))
    '#mvd.100!'
    """
    return _command("hold_depth", "mvd", depth_cm=depth_cm)


def move(direction_deg: int, power_percent: int) -> Command:
    """``#th.A.P!``: direction 0–360° clockwise from the bow, power 0–100 %.

    >>> str(move(270, 25))
    '#th.270.25!'
    """
    return _command("move", "th", direction_deg=direction_deg, power_percent=power_percent)


def depth_zero(raw: int) -> Command:
    """``#sdz.N!``, the raw pressure reading at the surface, 0–1024.

    >>> str(depth_zero(512))
    '#sdz.512!'
    """
    return _command("set_depth_zero", "sdz", raw=raw)


def depth_scale(k: int) -> Command:
    """``#sdk.N!``, the depth coefficient k, 0–10000.

    >>> str(depth_scale(1000))
    '#sdk.1000!'
    """
    return _command("set_depth_scale", "sdk", k=k)


def raw_frame(frame: str | bytes) -> bytes:
    """The bytes of a raw frame, sent as they are (ASCII text or bytes, not empty).

    >>> raw_frame("#qd!")
    b'#qd!'
    """
    if isinstance(frame, str):
        if not frame.isascii():
            raise ValueError(f"send_raw: frame must be ASCII, got {frame!r}")
        frame = frame.encode("ascii")
    if not isinstance(frame, bytes | bytearray):
        raise TypeError(f"send_raw: frame must be text or bytes, got {frame!r}")
    if not frame:
        raise ValueError(f"send_raw: frame must not be empty, got {frame!r}")
    return bytes(frame)


def any_command(command: Command) -> Command:
    """The argument of ``send``, checked: a :class:`~rovlink.protocol.Command` (text and frames
    have their own ways in, which a TypeError names: ``send_raw`` only for a frame, since words
    sent raw are no frame and the controller ignores them).

    >>> any_command("th 90 40")  # doctest: +NORMALIZE_WHITESPACE
    Traceback (most recent call last):
    ...
    TypeError: send: command must be a rovlink.protocol.Command, got 'th 90 40' (text as typed:
    send(parse_command_text('th 90 40')))
    """
    if isinstance(command, Command):
        return command
    hint = ""
    if isinstance(command, str) and command.lstrip().startswith("#"):
        hint = (
            f" (a frame: send(parse_command_text({command!r})), or exactly as it is: "
            f"send_raw({command!r}))"
        )
    elif isinstance(command, str):
        hint = f" (text as typed: send(parse_command_text({command!r})))"
    elif isinstance(command, bytes):
        hint = f" (a frame exactly as it is: send_raw({command!r}))"
    raise TypeError(f"send: command must be a rovlink.protocol.Command, got {command!r}{hint}")
