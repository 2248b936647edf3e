"""The host driver's exceptions: a caller's mistake, a query without a valid reply, a lost link.

Every one subclasses the built-in exception a caller would reach for first (``ValueError``,
``TimeoutError``, ``ConnectionError``), so ``except TimeoutError`` works without importing
rovlink, and :class:`ClientError` catches everything the driver raises about the link.
"""

from __future__ import annotations

from collections.abc import Sequence

from rovlink.protocol import Command

__all__ = [
    "ClientError",
    "ConnectError",
    "ConnectionLostError",
    "InvalidArgumentError",
    "QueryTimeoutError",
    "SupersededByStopError",
]


class ClientError(Exception):
    """Base of the errors about the link to the controller.

    >>> issubclass(QueryTimeoutError, ClientError), issubclass(ConnectError, ClientError)
    (True, True)
    """


class InvalidArgumentError(ValueError):
    """A driver method got a value outside its range; nothing was sent.

    >>> str(InvalidArgumentError("move", "power_percent", 150, "0–100", "th"))
    'move: power_percent must be in 0–100 (#th), got 150'
    >>> str(InvalidArgumentError("move", "direction_deg", 1.5, "0–360", "th"))
    'move: direction_deg must be a whole number in 0–360 (#th), got 1.5'
    """

    def __init__(
        self, method: str, argument: str, value: object, range_text: str, frame_name: str
    ) -> None:
        self.method = method
        self.argument = argument
        self.value = value
        self.range_text = range_text
        # (A value in range but not whole, 1.5 degrees, is told so, not that it is out of range.)
        whole = "a whole number " if isinstance(value, float) and not value.is_integer() else ""
        super().__init__(
            f"{method}: {argument} must be {whole}in {range_text} (#{frame_name}), got {value!r}"
        )


class QueryTimeoutError(ClientError, TimeoutError):
    """A query got no valid reply, however many times it was retried.

    ``query`` is the command, ``failures`` says what happened to each attempt (``timeout``:
    nothing arrived in time; ``corrupt``: the reply failed its checksum or was malformed;
    ``lost``: the controller answered a later query first), ``port`` the link it was sent on
    (``None``: not said).

    >>> from rovlink.protocol import Command
    >>> str(QueryTimeoutError(Command("qd"), ["timeout", "corrupt"], 0.5, "/dev/ttyUSB0"))
    '#qd! got no valid reply within 0.5 s (2 attempts: timeout, corrupt) on /dev/ttyUSB0'
    """

    def __init__(
        self, query: Command, failures: Sequence[str], timeout_s: float, port: str | None = None
    ) -> None:
        self.query = query
        self.failures = tuple(failures)
        self.timeout_s = timeout_s
        self.port = port
        attempts = len(self.failures)
        noun = "attempt" if attempts == 1 else "attempts"
        # (Where: a program driving two robots, or a tool, says which link did not answer.)
        on_port = f" on {port}" if port is not None else ""
        super().__init__(
            f"{query} got no valid reply within {timeout_s:g} s "
            f"({attempts} {noun}: {', '.join(self.failures)}){on_port}"
        )


class ConnectionLostError(ClientError, ConnectionError):
    """The link is gone (adapter unplugged, socket closed, or ``close()`` called).

    Raised by the call that was waiting when it happened and by every later call.

    >>> import rovlink
    >>> rov = rovlink.connect("sim://")
    >>> rov.close()
    >>> rov.depth_cm()
    Traceback (most recent call last):
    ...
    rovlink.client.errors.ConnectionLostError: connection lost: simulated controller: closed
    """


class ConnectError(ClientError, ConnectionError):
    """The URL could not be opened (no such device, port in use, nothing listening), or the
    controller closed the link before it answered.

    >>> import rovlink
    >>> rovlink.connect("/dev/no-such-port")
    Traceback (most recent call last):
    ...
    rovlink.client.errors.ConnectError: cannot open /dev/no-such-port: ...

    ``setting`` names the setting of :func:`rovlink.connect` that the message asks to change,
    as it says it there (``retries=N``), so that a command line can say its option instead.
    """

    def __init__(self, *args: object, setting: str | None = None) -> None:
        super().__init__(*args)
        #: The keyword of ``connect`` the message names as ``keyword=N``, if any.
        self.setting = setting


def checksum_mode_unconfirmed(link: str, algorithm: str, error: QueryTimeoutError) -> ConnectError:
    """The error of an open in checksum mode whose first checksummed query, ``error``, got no
    valid reply. Its attempts tell the causes apart: every attempt timed out when the
    controller dropped each query (another algorithm, or no checksum mode); a reply that failed
    the check shows it took the query, and a noisy line (or replies checksummed otherwise)
    spoilt the replies, which asking about the algorithm alone would hide.

    >>> from rovlink.protocol import Command
    >>> noisy = QueryTimeoutError(Command("qd"), ["corrupt", "timeout"], 0.5)
    >>> print(checksum_mode_unconfirmed("sim", "crc8", noisy))
    sim: the controller answers in checksum mode, but no reply passed the crc8 check (a noisy \
line? more attempts: retries=N; or its replies are checksummed with another algorithm): #qd! got \
no valid reply within 0.5 s (2 attempts: corrupt, timeout)
    """
    if "corrupt" in error.failures:
        return ConnectError(
            f"{link}: the controller answers in checksum mode, but no reply passed the "
            f"{algorithm} check (a noisy line? more attempts: retries=N; or its replies are "
            f"checksummed with another algorithm): {error}",
            setting="retries",
        )
    return ConnectError(
        f"{link}: the controller answers, but not in checksum mode with {algorithm} (is that "
        f"its algorithm?): {error}"
    )


class SupersededByStopError(ClientError):
    """A command that unlocks the motors or moves the robot was still waiting to be written
    when ``stop()`` was called (from another thread or task): it was not sent, as it would have
    gone out after the ``#stop!`` and undone it. ``command`` is the command not sent.

    >>> from rovlink.protocol import Command
    >>> print(SupersededByStopError(Command("start")))  # doctest: +NORMALIZE_WHITESPACE
    #start! not sent: stop() was called while it waited to be written, and a stop supersedes
    the unlock and motion commands asked for before it
    """

    def __init__(self, command: Command) -> None:
        self.command = command
        super().__init__(
            f"{command} not sent: stop() was called while it waited to be written, and a stop "
            "supersedes the unlock and motion commands asked for before it"
        )
