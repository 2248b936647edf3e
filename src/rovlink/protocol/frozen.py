"""Immutable value classes without :mod:`dataclasses`, which costs more to import (with
:mod:`inspect` and :mod:`ast`) than the rest of ``rovlink decode``'s start together.

A class declares its ``__slots__``, writes its own ``__init__`` (setting the slots with
``object.__setattr__``) and names its fields in ``__match_args__``; :func:`frozen` adds what
``@dataclass(frozen=True, slots=True)`` would add for those fields: the ``repr``, equality and
hash by field values, assignment and deletion refused, and copying and pickling.

>>> @frozen
... class Point:
...     __slots__ = ("x", "y")
...     __match_args__ = ("x", "y")
...     x: int
...     y: int
...
...     def __init__(self, x: int, y: int = 0) -> None:
...         object.__setattr__(self, "x", x)
...         object.__setattr__(self, "y", y)
>>> Point(1, 2), Point(1) == Point(1, 0), len({Point(1), Point(1, 0)})
(Point(x=1, y=2), True, 1)
>>> Point(1).x = 5
Traceback (most recent call last):
...
AttributeError: cannot assign to field 'x'
"""

from __future__ import annotations

from operator import attrgetter

# Not typing's: this module is on the start-up path of ``rovlink decode``.
TYPE_CHECKING = False

if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Any, TypeVar

    from typing_extensions import dataclass_transform

    _T = TypeVar("_T")
else:

    def dataclass_transform(**_options: object) -> Callable[[_T], _T]:
        return lambda function: function


__all__ = ["frozen"]


@dataclass_transform(frozen_default=True)
def frozen(cls: type[_T]) -> type[_T]:
    """Make ``cls`` a frozen value class over the fields in its ``__match_args__`` (to the type
    checker, a frozen dataclass).

    Fields outside ``__match_args__`` (set by ``__init__`` from the others) take no part in the
    ``repr``, equality or hash, as ``field(init=False, repr=False, compare=False)`` would; every
    slot is kept by copies and pickles.
    """
    fields: tuple[str, ...] = cls.__match_args__  # type: ignore[attr-defined]
    slots = tuple(
        name for klass in reversed(cls.__mro__) for name in klass.__dict__.get("__slots__", ())
    )
    # A tuple of the fields' values, as dataclasses compare and hash them (attrgetter of one
    # name gives the bare value).
    key: Callable[[object], tuple[Any, ...]] = (
        attrgetter(*fields) if len(fields) > 1 else lambda self: (getattr(self, fields[0]),)
    )
    get_state = attrgetter(*slots) if len(slots) > 1 else lambda self: (getattr(self, slots[0]),)

    def repr_(self: object) -> str:
        shown = ", ".join(
            f"{name}={value!r}" for name, value in zip(fields, key(self), strict=True)
        )
        return f"{type(self).__qualname__}({shown})"

    def eq(self: object, other: object) -> object:  # a bool, or NotImplemented
        if self is other:
            return True
        if other.__class__ is self.__class__:
            return key(self) == key(other)
        return NotImplemented

    def hash_(self: object) -> int:
        return hash(key(self))

    def setattr_(self: object, name: str, value: object) -> None:
        raise AttributeError(f"cannot assign to field {name!r}")

    def delattr_(self: object, name: str) -> None:
        raise AttributeError(f"cannot delete field {name!r}")

    def getstate(self: object) -> tuple[Any, ...]:
        return get_state(self)

    def setstate(self: object, state: tuple[Any, ...]) -> None:
        for name, value in zip(slots, state, strict=True):
            object.__setattr__(self, name, value)

    methods = {
        "__repr__": repr_,
        "__eq__": eq,
        "__hash__": hash_,
        "__setattr__": setattr_,
        "__delattr__": delattr_,
        "__getstate__": getstate,
        "__setstate__": setstate,
    }
    for name, method in methods.items():
        method.__name__ = name
        method.__qualname__ = f"{cls.__qualname__}.{name}"
        setattr(cls, name, method)
    return cls
