"""MAVLink FTP (FILE_TRANSFER_PROTOCOL) refused at once: the vehicle has no files.

Ground stations try FTP before the older protocols: MAVProxy asks for the parameters as the file
``@PARAM/param.pck`` and, without an answer, retries for about ten seconds before it falls back
to PARAM_REQUEST_LIST. Every request is therefore answered with a NAK (``UnknownCommand``), as
the FTP protocol has a server answer an operation it does not carry out; the ground station
moves on to the message protocols straight away.
"""

from __future__ import annotations

import struct

__all__ = ["ERROR_UNKNOWN_COMMAND", "OPCODE_NAK", "refusal"]

#: The header of an FTP payload: seq (uint16), session, opcode, size, req_opcode,
#: burst_complete, padding (uint8 each), offset (uint32).
_HEADER = struct.Struct("<HBBBBBBI")
_PAYLOAD_BYTES = 251
_OPCODE_NONE = 0
_OPCODE_ACK = 128
#: The reply that refuses a request.
OPCODE_NAK = 129
#: NAK error code: the server does not carry out this operation.
ERROR_UNKNOWN_COMMAND = 7


def refusal(request: bytes | list[int]) -> list[int] | None:
    """The payload of the NAK that answers FTP payload ``request``; ``None`` when ``request``
    is no request (a reply, or too short to be one).

    >>> open_file = list(struct.pack("<HBBBBBBI", 3, 9, 4, 0, 0, 0, 0, 0)) + [0] * 239
    >>> nak = refusal(open_file)
    >>> _HEADER.unpack(bytes(nak[:12])), nak[12], len(nak)
    ((4, 9, 129, 1, 4, 0, 0, 0), 7, 251)
    >>> refusal(nak) is None  # a NAK is not answered
    True
    """
    data = bytes(request)
    if len(data) < _HEADER.size:
        return None
    seq, session, opcode, *_ = _HEADER.unpack_from(data)
    if opcode in (_OPCODE_NONE, _OPCODE_ACK, OPCODE_NAK):
        return None
    header = _HEADER.pack((seq + 1) & 0xFFFF, session, OPCODE_NAK, 1, opcode, 0, 0, 0)
    payload = header + bytes([ERROR_UNKNOWN_COMMAND])
    return list(payload.ljust(_PAYLOAD_BYTES, b"\0"))
