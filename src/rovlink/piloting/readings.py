"""Replies in words, from the command table: ``$qd.123!`` is ``qd → 123 cm``."""

from __future__ import annotations

from rovlink.protocol import Argument, Response

__all__ = ["reading_text", "reply_text", "value_text"]

# Units by the suffix of an argument's name in the command table.
_UNITS = {"_cm": " cm", "_deg": "°", "_percent": " %"}


def value_text(argument: Argument, value: int) -> str:
    """One value with its unit, signed where the table says it is.

    >>> from rovlink.protocol import lookup, Kind
    >>> value_text(lookup("qro", Kind.RESPONSE).arguments[0], 15)
    '+15°'
    """
    text = argument.format(value)
    for suffix, unit in _UNITS.items():
        if argument.name.endswith(suffix):
            return text + unit
    return text


def reading_text(response: Response) -> str:
    """What a reply says: ``123 cm``, ``-1°``, ``530 (raw)``, ``LEAK (latched)``.

    >>> reading_text(Response("qd", (123,)))
    '123 cm'
    >>> reading_text(Response("q.l", (1,)))
    'LEAK: the sensor fired since the last reset'
    """
    if response.name == "q.l":
        return "LEAK: the sensor fired since the last reset" if response.values[0] else "no leak"
    if response.name == "qr":
        return f"{response.values[0]} (raw)"
    return ", ".join(
        value_text(argument, value)
        for argument, value in zip(response.spec.arguments, response.values, strict=True)
    )


def reply_text(response: Response) -> str:
    """The reply's name and what it says: ``qd → 123 cm``.

    >>> reply_text(Response("qhe", (275,)))
    'qhe → 275°'
    """
    return f"{response.name} → {reading_text(response)}"
