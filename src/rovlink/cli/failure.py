"""How a command reports that it cannot go on: one line on stderr and an exit status."""

from __future__ import annotations

TYPE_CHECKING = False  # (typing stays off the command line's start-up path)
if TYPE_CHECKING:
    from typing import TextIO

__all__ = [
    "CommandError",
    "InputError",
    "NoTerminalError",
    "UsageError",
    "error_number",
    "is_terminal",
    "reason",
    "unreadable",
]


class UsageError(Exception):
    """The command line was wrong (exit status 2, with the command's usage line).

    Raised for what argparse cannot check itself, e.g. a command text that does not parse.
    """


class CommandError(Exception):
    """The command ran and failed (exit status 1); the message is the whole story, one line.

    >>> str(CommandError("cannot open /dev/ttyUSB9: No such file or directory"))
    'cannot open /dev/ttyUSB9: No such file or directory'
    """

    exit_status = 1


class InputError(CommandError):
    """A file the command was given is unusable (exit status 2, like a usage error, but one
    line: the file's content, not the command line, is what to fix).

    >>> InputError("robot.toml: not UTF-8 text").exit_status
    2
    """

    exit_status = 2


class NoTerminalError(CommandError):
    """The command draws on a terminal and reads its keys, and was run without one (exit
    status 2, one line: the way it was run, not its command line, is what to change).

    >>> NoTerminalError("needs a terminal").exit_status
    2
    """

    exit_status = 2


def is_terminal(stream: TextIO | None) -> bool:
    """Whether ``stream`` is a terminal, the test before a :class:`NoTerminalError`: not when
    there is no stream (``sys.stdin`` is ``None`` without one) or it is closed.

    >>> import io
    >>> is_terminal(io.StringIO()), is_terminal(None)
    (False, False)
    """
    try:
        return stream is not None and stream.isatty()
    except (ValueError, OSError):  # closed
        return False


def reason(error: BaseException) -> str:
    """Why a file, port or socket operation failed, in the system's words alone: the message
    around it names the file once, so not ``str(error)`` with its "[Errno N]" and file name.

    The deepest error number is used: pyserial and the driver wrap the system's error in
    their own, whose text repeats it.

    >>> reason(FileNotFoundError(2, "No such file or directory", "/x"))
    'No such file or directory'
    >>> reason(OSError(21, "could not open port /tmp: [Errno 21] Is a directory: '/tmp'"))
    'Is a directory'

    A name that does not resolve (``socket.gaierror``, whose numbers are not the system's) is
    said in the resolver's words, from wherever it is in the chain.
    """
    code = error_number(error)
    if code is not None and code > 0:  # (socket.gaierror's are negative: not the system's)
        import os  # noqa: PLC0415 - loaded by the interpreter anyway; kept off the start-up path

        return os.strerror(code)
    words = None
    cause: BaseException | None = error
    while cause is not None:
        words = getattr(cause, "strerror", None) or words
        cause = cause.__cause__ or cause.__context__
    return words or str(error)


def error_number(error: BaseException) -> int | None:
    """The error number of the innermost error in ``error``'s chain that has one."""
    code = None
    cause: BaseException | None = error
    while cause is not None:
        if isinstance(cause, OSError) and cause.errno:
            code = cause.errno
        elif len(cause.args) == 2 and isinstance(cause.args[0], int):
            code = cause.args[0]  # termios.error: (errno, message), not an OSError
        cause = cause.__cause__ or cause.__context__
    return code


def unreadable(path: object, error: OSError | UnicodeDecodeError) -> InputError:
    """A text file given to the command that cannot be read, in one line naming it once.

    >>> str(unreadable("/x.param", FileNotFoundError(2, "No such file or directory", "/x")))
    '/x.param: cannot read: No such file or directory'
    """
    if isinstance(error, UnicodeDecodeError):
        return InputError(f"{path}: not UTF-8 text")
    return InputError(f"{path}: cannot read: {reason(error)}")
