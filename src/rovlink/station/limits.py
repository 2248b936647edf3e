"""The limits the page's settings and controls use, read from the command table.

The page never restates a range: the server sends these in its ``hello`` message and the page
builds its settings panel (PID gains, max PWM, depth calibration) and its checks from them.
"""

from __future__ import annotations

from typing import Any

from rovlink.protocol import lookup
from rovlink.station.messages import PAGE_COMMANDS

__all__ = ["command_limits"]

#: The motion commands the relay sends: the page scales its sticks to their ranges.
_MOTION_COMMANDS = ("th", "mvs")


def command_limits() -> dict[str, dict[str, Any]]:
    """Each command a page may send or make the relay send: its description and arguments.

    >>> command_limits()["mgmp"]["arguments"][0]["max"]
    255
    >>> [argument["name"] for argument in command_limits()["th"]["arguments"]]
    ['direction_deg', 'power_percent']
    """
    limits: dict[str, dict[str, Any]] = {}
    for name in (*PAGE_COMMANDS, *_MOTION_COMMANDS):
        spec = lookup(name)
        limits[name] = {
            "description": spec.description,
            "arguments": [
                {
                    "name": argument.name,
                    "min": argument.minimum,
                    "max": argument.maximum,
                    "signed": argument.signed,
                    "unit": argument.unit,
                    "description": argument.description,
                }
                for argument in spec.arguments
            ],
        }
    return limits
