"""Typed, frozen messages: one command (``#…!``) or one response (``$…!``) with its values.

A message is validated against the command table when it is made, so an invalid message cannot
exist: out-of-range or missing values raise :class:`ArgumentError`, naming the command, the
argument and its range.
"""

from __future__ import annotations

from rovlink.protocol.commands import COMMANDS, Kind, Setting, Spec, UnknownCommandError, lookup
from rovlink.protocol.frozen import frozen

# Not typing's: the protocol core is on the start-up path of ``rovlink decode``.
TYPE_CHECKING = False

if TYPE_CHECKING:
    from typing import TypeVar

    M = TypeVar("M", bound="Message")

__all__ = [
    "ArgumentCountError",
    "ArgumentError",
    "Command",
    "Message",
    "Response",
    "setting_command",
    "trusted_message",
]


class ArgumentError(ValueError):
    """A value outside its argument's range (a caller's mistake, not the peer's)."""

    def __init__(self, spec: Spec, index: int, value: int) -> None:
        argument = spec.arguments[index]
        self.command = spec.name
        self.argument = argument.name
        self.value = value
        super().__init__(
            f"{spec.name}: {argument.name} must be in {argument.range_text()}, got {value}"
        )


class ArgumentCountError(ValueError):
    """The wrong number of values for a command."""

    def __init__(self, spec: Spec, count: int) -> None:
        self.command = spec.name
        names = ", ".join(argument.name for argument in spec.arguments) or "no arguments"
        super().__init__(f"{spec.name} takes {len(spec.arguments)} value(s) ({names}), got {count}")


def _validate(spec: Spec, values: tuple[int, ...]) -> None:
    if len(values) != len(spec.arguments):
        raise ArgumentCountError(spec, len(values))
    for index, (argument, value) in enumerate(zip(spec.arguments, values, strict=True)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError(f"{spec.name}: {argument.name} must be an int, got {value!r}")
        if not argument.check(value):
            raise ArgumentError(spec, index, value)


@frozen
class Message:
    """Base of :class:`Command` and :class:`Response`: a frame name and its integer values.

    ``name`` is the canonical spelling (``mvpidd`` also for the alias ``mvpdd``). ``spec``, the
    name's entry in the command table, is derived from it: it is neither shown nor compared.
    """

    __slots__ = ("name", "spec", "values")
    __match_args__ = ("name", "values")

    name: str
    values: tuple[int, ...]
    spec: Spec

    kind = Kind.COMMAND

    def __init__(self, name: str, values: tuple[int, ...] = ()) -> None:
        try:
            spec = lookup(name, self.kind)
        except UnknownCommandError:
            raise UnknownCommandError(f"unknown {self.kind.value} {name!r}") from None
        values = tuple(values)
        _validate(spec, values)
        _set_name(self, spec.name)
        _set_values(self, values)
        _set_spec(self, spec)

    @property
    def body(self) -> str:
        """The frame body as the controller writes it, without checksum: ``th.270.25``."""
        return self.spec.body(self.values)

    def __str__(self) -> str:
        return self.kind.start_byte.decode() + self.body + "!"


# The slots' own setters: the frozen class refuses assignment, and these are quicker than
# ``object.__setattr__`` for the decoders' hot path (:func:`trusted_message`).
_set_name = Message.__dict__["name"].__set__
_set_values = Message.__dict__["values"].__set__
_set_spec = Message.__dict__["spec"].__set__


# The subclasses add no fields (an empty ``__slots__``: no slot of the base's declared again, which
# would shadow it) and share the base's methods, which show and compare the class too.
class Command(Message):
    """A frame from host to controller, e.g. ``Command("th", (270, 25))`` is ``#th.270.25!``.

    >>> str(Command("mvs", (-50,)))
    '#mvs.-50!'
    """

    __slots__ = ()

    kind = Kind.COMMAND

    @property
    def setting(self) -> tuple[Setting, bool] | None:
        """The on/off state this command switches and the value it sets, if any.

        >>> Command("mvdirect", (1,)).setting
        (<Setting.DIRECT_MODE: 'direct_mode'>, True)
        >>> Command("qd").setting is None
        True
        """
        spec = self.spec
        if spec.setting is None:
            return None
        value = spec.setting_value
        return spec.setting, bool(self.values[0]) if value is None else value


def setting_command(setting: Setting, value: bool) -> Command:
    """The command that switches ``setting`` to ``value`` (the other half of a toggle pair).

    >>> str(setting_command(Setting.CHECKSUM, False))
    '#crcoff!'
    >>> str(setting_command(Setting.DIRECT_MODE, True))
    '#mvdirect.1!'
    """
    for spec in COMMANDS:
        if spec.setting is setting:
            if spec.setting_value is None:
                return Command(spec.name, (int(value),))
            if spec.setting_value is value:
                return Command(spec.name)
    raise ValueError(f"no command sets {setting} to {value}")  # pragma: no cover - table error


class Response(Message):
    """A frame from controller to host, e.g. ``Response("qro", (-1,))`` is ``$qro.-1!``.

    >>> str(Response("qro", (0,)))
    '$qro.+0!'
    """

    __slots__ = ()

    kind = Kind.RESPONSE


_new = object.__new__


def trusted_message(cls: type[M], spec: Spec, values: tuple[int, ...]) -> M:
    """A message of already validated values, made without validating them again.

    For decoders on their hot path, which have just checked every value against ``spec``.
    """
    message = _new(cls)
    _set_name(message, spec.name)
    _set_values(message, values)
    _set_spec(message, spec)
    return message
