"""Why a connection to the broker failed or was lost, in words an operator can act on.

aiomqtt passes on the system's raw text (``[Errno 111] Connection refused``, ``[Errno -2] Name
or service not known``) or an MQTT reason code (``[code:135] Not authorized``); the error that
says what happened is somewhere in its chain (aiomqtt raises its own ``from None``, which keeps
the original as the context).
"""

from __future__ import annotations

import os
import re
import socket
import ssl

from rovlink.bridges.mqtt.broker import BrokerSettings

__all__ = ["broker_failure"]

#: aiomqtt's text for a reply (CONNACK, SUBACK, PUBACK) not come within its timeout.
_NO_REPLY = "Operation timed out"
#: MQTT reason codes that refuse a login: 3.1.1's 4 and 5, MQTT 5's 134 and 135.
_LOGIN_REFUSED = {4, 5, 134, 135}
#: MQTT 5's "Unspecified error", which paho also gives a connection closed under it.
_UNSPECIFIED = 0x80
_CODE_PREFIX = re.compile(r"^\[code:\d+\]\s*")


def broker_failure(
    error: BaseException, broker: BrokerSettings, *, connected: bool, reply_timeout_s: float
) -> str:
    """What happened to the connection to ``broker`` (``connected``: it was up and was lost;
    else it could not be made), from aiomqtt's ``error``: ``cannot connect: connection refused
    (…)``, ``connection lost: the broker said Server shutting down``.

    >>> refused = ConnectionRefusedError(111, "Connection refused")
    >>> broker = BrokerSettings("127.0.0.1", 1)
    >>> broker_failure(refused, broker, connected=False, reply_timeout_s=5)
    'cannot connect: connection refused (is the broker running, and listening on port 1?)'
    """
    what = "connection lost" if connected else "cannot connect"
    return f"{what}: {_why(error, broker, connected, reply_timeout_s)}"


def _chain(error: BaseException) -> list[BaseException]:
    chain: list[BaseException] = []
    cause: BaseException | None = error
    while cause is not None and cause not in chain:
        chain.append(cause)
        cause = cause.__cause__ or cause.__context__
    return chain


def _why(error: BaseException, broker: BrokerSettings, connected: bool, timeout_s: float) -> str:
    chain = _chain(error)
    for cause in chain:  # the system's error first: it says what happened on the network
        if isinstance(cause, ssl.SSLCertVerificationError):
            return (
                f"TLS failure: the broker's certificate was not accepted "
                f"({cause.verify_message or cause.reason}): give the CA that signed it, and "
                f"reach the broker by a name the certificate holds"
            )
        if isinstance(cause, ssl.SSLError):
            return f"TLS failure ({cause.reason or cause}): is port {broker.port} a TLS listener?"
        if isinstance(cause, socket.gaierror):
            words = cause.strerror or str(cause)
            return f"name not resolved: the host {broker.host!r} is unknown ({words})"
        if isinstance(cause, ConnectionRefusedError):
            return (
                f"connection refused (is the broker running, and listening on port {broker.port}?)"
            )
        if isinstance(cause, ConnectionResetError) and broker.tls and not connected:
            return (
                f"TLS failure: the connection was reset in the TLS handshake (is port "
                f"{broker.port} a TLS listener?)"
            )
    if str(error) == _NO_REPLY:
        if connected:
            return f"the broker answered nothing within {timeout_s:g} s (stalled or overloaded)"
        expects_tls = "" if broker.tls else ", or one that expects TLS: mqtts://"
        return (
            f"no answer to the MQTT connection within {timeout_s:g} s (a stalled or overloaded "
            f"broker{expects_tls})"
        )
    for cause in chain:
        if isinstance(cause, OSError) and cause.errno is not None and cause.errno > 0:
            return f"network error: {os.strerror(cause.errno)}"
        if isinstance(cause, TimeoutError):  # (a TCP handshake nobody answered)
            return "no answer to the TCP connection (a host that is down, or a firewall)"
    for cause in chain:  # an MQTT reason code: the broker's own words
        code = getattr(cause, "rc", None)
        if code is None:
            continue
        words = _CODE_PREFIX.sub("", str(cause)).rstrip(".")
        if getattr(code, "value", code) in _LOGIN_REFUSED:
            return (
                f"the broker refused the login: {words} (check the user name, the password "
                "and the broker's access control)"
            )
        if getattr(code, "value", code) == _UNSPECIFIED:
            return "the connection was closed, no reason given (the broker stopped, or the network)"
        if not isinstance(code, int):  # (a reason code the broker sent)
            return f"the broker said {words}" if connected else f"the broker refused: {words}"
        return words  # (the MQTT client's own: "The connection was lost")
    return _CODE_PREFIX.sub("", str(error)) or type(error).__name__
