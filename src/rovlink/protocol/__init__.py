"""The protocol core, sans-I/O: command table, messages, checksums, encoder and streaming decoder.

Nothing here touches sockets, threads, clocks or the terminal, and nothing imports a third-party
package, so it runs as it is on a small board.

>>> from rovlink.protocol import Command, Decoder, encode
>>> encode(Command("mvd", (100,)), checksum="crc8")
b'#mvd.1004B!'
>>> Decoder().feed(b"$qd.123!")[0].message.values
(123,)
"""

from rovlink.protocol.checksum import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    ChecksumAlgorithm,
    UnknownAlgorithmError,
    get_algorithm,
)
from rovlink.protocol.commands import (
    COMMANDS,
    RESPONSES,
    Argument,
    Kind,
    Setting,
    Spec,
    UnknownCommandError,
    VerticalMode,
    lookup,
)
from rovlink.protocol.decoder import MAX_TEXT_BYTES, BadFrame, Decoder, Event, Frame, Text
from rovlink.protocol.frames import MAX_FRAME_BYTES, FrameError, Reason, encode, parse_body
from rovlink.protocol.messages import (
    ArgumentCountError,
    ArgumentError,
    Command,
    Message,
    Response,
    setting_command,
)

__all__ = [
    "ALGORITHMS",
    "COMMANDS",
    "DEFAULT_ALGORITHM",
    "MAX_FRAME_BYTES",
    "MAX_TEXT_BYTES",
    "RESPONSES",
    "Argument",
    "ArgumentCountError",
    "ArgumentError",
    "BadFrame",
    "ChecksumAlgorithm",
    "Command",
    "Decoder",
    "Event",
    "Frame",
    "FrameError",
    "Kind",
    "Message",
    "Reason",
    "Response",
    "Setting",
    "Spec",
    "Text",
    "UnknownAlgorithmError",
    "UnknownCommandError",
    "VerticalMode",
    "encode",
    "get_algorithm",
    "lookup",
    "parse_body",
    "setting_command",
]
