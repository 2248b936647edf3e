"""The host driver, blocking: ``rovlink.connect(url)`` returns a :class:`Client`.

>>> from rovlink.client import parse_command_text
>>> str(parse_command_text("th 270 25"))
'#th.270.25!'

Example::

    import rovlink

    with rovlink.connect("sim://") as rov:
        rov.start()
        rov.hold_depth(100)
        print(rov.sensors())
        rov.stop()
"""

from rovlink.client.blocking import Client, connect
from rovlink.client.command_text import CommandTextError, parse_command_text, usage
from rovlink.client.counters import LinkCounters
from rovlink.client.errors import (
    ClientError,
    ConnectError,
    ConnectionLostError,
    InvalidArgumentError,
    QueryTimeoutError,
    SupersededByStopError,
)
from rovlink.client.events import ClientEvent, EventCallback
from rovlink.client.options import ClientOptions
from rovlink.client.schemes import register_scheme
from rovlink.client.sensors import Sensors
from rovlink.client.url import parse_url

__all__ = [
    "Client",
    "ClientError",
    "ClientEvent",
    "ClientOptions",
    "CommandTextError",
    "ConnectError",
    "ConnectionLostError",
    "EventCallback",
    "InvalidArgumentError",
    "LinkCounters",
    "QueryTimeoutError",
    "Sensors",
    "SupersededByStopError",
    "connect",
    "parse_command_text",
    "parse_url",
    "register_scheme",
    "usage",
]
