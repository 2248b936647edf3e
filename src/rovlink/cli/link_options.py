"""The options of every command that talks to a controller, defined once.

:func:`add_link_options` puts them on a command's parser, each checked as it is read (a bad
value is a one-line usage error naming the option); :func:`client_options` turns them into the
driver's one settings object, :class:`~rovlink.client.options.ClientOptions`. A new connection
setting is an option here and a line in :func:`client_options`. :func:`ask` and
:func:`confirmed` are the questions such commands put before they act (``--yes`` skips them).
"""

from __future__ import annotations

import argparse

from rovlink.cli.failure import CommandError, UsageError, error_number, reason
from rovlink.protocol import ALGORITHMS, DEFAULT_ALGORITHM

# Not typing's: ``rovlink decode`` imports this module, and typing costs a fifth of its start-up.
TYPE_CHECKING = False

if TYPE_CHECKING:
    from collections.abc import Awaitable, Callable
    from types import TracebackType

    from rovlink.aio import AsyncClient
    from rovlink.client import Client, ClientOptions
    from rovlink.client.links import Link
    from rovlink.client.options import StrayCallback
    from rovlink.recorder import Recorder

    #: Called with ``">>"`` and the bytes written, ``"<<"`` and the bytes read (``send --raw``).
    ShowBytes = Callable[[str, bytes], None]

__all__ = [
    "DEFAULT_REPLY_TIMEOUT_S",
    "DEFAULT_URL",
    "MAX_RETRIES",
    "MAX_TIMEOUT_S",
    "add_hearing_option",
    "add_link_options",
    "algorithm_name",
    "ask",
    "baud_rate",
    "client_options",
    "confirmed",
    "connect",
    "connect_async",
    "file_name",
    "hear_other_lines_if_asked",
    "log_warnings",
    "positive_int",
    "reply_timeout",
    "seconds",
]

DEFAULT_URL = "sim://"
#: The driver's default (kept here as a number: the driver is not imported to show the help).
DEFAULT_BOOT_TIMEOUT_S = 3.0
#: The driver's reply timeout (``--timeout``), which ``record`` assumes of a tap's program.
DEFAULT_REPLY_TIMEOUT_S = 0.5
#: Longer than any controller takes to answer; larger values are typing mistakes.
MAX_TIMEOUT_S = 3600.0
MIN_TIMEOUT_S = 0.001
MAX_RETRIES = 100
_URL_HELP = "serial device, pyserial URL (socket://HOST:PORT, rfc2217://…) or sim:// (simulator)"


def bounded_float(text: str, minimum: float, maximum: float, unit: str = "") -> float:
    """A finite number within ``minimum``–``maximum``, for argparse's ``type=``.

    >>> bounded_float("1e10", 0.001, 3600, " s")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: 1e10 s is more than the maximum, 3600 s
    """
    import math  # noqa: PLC0415 - not on the start-up path of decode, which has no such option

    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number")
    if value < minimum:
        raise argparse.ArgumentTypeError(
            f"{text}{unit} is less than the minimum, {minimum:g}{unit}"
        )
    if value > maximum:
        raise argparse.ArgumentTypeError(
            f"{text}{unit} is more than the maximum, {maximum:g}{unit}"
        )
    return value


def seconds(text: str, *, minimum: float = 0.0, maximum: float = MAX_TIMEOUT_S) -> float:
    """A number of seconds within ``minimum``–``maximum``, for argparse's ``type=``.

    >>> seconds("0.25")
    0.25
    """
    return bounded_float(text, minimum, maximum, " s")


def reply_timeout(text: str) -> float:
    """A reply timeout, for argparse's ``type=``: :func:`seconds`, at least 1 ms."""
    return seconds(text, minimum=MIN_TIMEOUT_S)


def bounded_int(text: str, minimum: int, maximum: int) -> int:
    """An integer within ``minimum``–``maximum``, for argparse's ``type=``.

    >>> bounded_int("99999999999999999999", 0, 100)
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: 99999999999999999999 is not in 0–100
    """
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not minimum <= value <= maximum:
        raise argparse.ArgumentTypeError(f"{text} is not in {minimum}–{maximum}")
    return value


def _optional_seconds(text: str) -> float | None:
    """Seconds, where 0 means "not at all" (``None`` to the driver)."""
    value = seconds(text)
    return value or None


def _retries(text: str) -> int:
    return bounded_int(text, 0, MAX_RETRIES)


def positive_int(text: str) -> int:
    """An integer ≥ 1, for argparse's ``type=`` (e.g. a baud rate)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} is not a positive integer")
    return value


def baud_rate(text: str) -> int:
    """A serial speed, 1 to :data:`rovlink.client.url.MAX_BAUDRATE`, for argparse's ``type=``.

    >>> baud_rate("99999999999999999999")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: 99999999999999999999 is more than the maximum, 12000000 baud
    """
    from rovlink.client.url import MAX_BAUDRATE  # noqa: PLC0415 - the client: not at start-up

    value = positive_int(text)
    if value > MAX_BAUDRATE:
        raise argparse.ArgumentTypeError(f"{text} is more than the maximum, {MAX_BAUDRATE} baud")
    return value


def file_name(text: str) -> str:
    """A file (or directory) name, for argparse's ``type=``: never empty, which would otherwise
    read as "not given" or as the current directory.

    >>> file_name("")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: an empty file name
    """
    if not text:
        raise argparse.ArgumentTypeError("an empty file name")
    return text


def algorithm_name(text: str) -> str:
    """A known checksum algorithm's name, for argparse's ``type=``; in any case, as a datasheet
    writes it (``CRC8``).

    >>> algorithm_name("CRC8")
    'crc8'
    >>> algorithm_name("md5")
    Traceback (most recent call last):
    ...
    argparse.ArgumentTypeError: unknown checksum algorithm 'md5'; known: crc8, sum8, xor
    """
    name = text.lower()
    if name not in ALGORITHMS:
        known = ", ".join(sorted(ALGORITHMS))
        raise argparse.ArgumentTypeError(f"unknown checksum algorithm {text!r}; known: {known}")
    return name


class OnOff(argparse.BooleanOptionalAction):
    """``--flag`` / ``--no-flag``, its help as given: Python 3.10–3.12 would append
    "(default: False)" to it."""

    def __init__(
        self, option_strings: list[str], dest: str, default: bool = False, help: str | None = None
    ) -> None:
        super().__init__(option_strings, dest, default=default)
        self.help = help


def add_checksum_options(parser: argparse.ArgumentParser, checksum_help: str) -> None:
    """``--checksum/--no-checksum`` and ``--algorithm`` (``decode`` has these alone)."""
    parser.add_argument(
        "--checksum", action=OnOff, default=False, help=f"{checksum_help} (default: off)"
    )
    parser.add_argument(
        "--algorithm",
        type=algorithm_name,
        action=GivenAlgorithm,
        default=DEFAULT_ALGORITHM,
        metavar="NAME",
        help=f"checksum algorithm: {', '.join(sorted(ALGORITHMS))} (default: %(default)s)",
    )


class GivenAlgorithm(argparse.Action):
    """``--algorithm NAME``, noting that it was given (``args.algorithm_given``): a simulated
    controller then takes it, where the default leaves it the one its URL or file names."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        setattr(namespace, self.dest, values)
        namespace.algorithm_given = True


def add_link_options(parser: argparse.ArgumentParser, *, url_required: bool = False) -> None:
    """The URL argument and the connection options, with their checks and defaults."""
    if url_required:
        parser.add_argument("url", metavar="URL", help=_URL_HELP)
    else:
        parser.add_argument(
            "url",
            metavar="URL",
            nargs="?",
            default=DEFAULT_URL,
            help=f"{_URL_HELP} (default: %(default)s)",
        )
    group = parser.add_argument_group("link options")
    group.add_argument(
        "--checksum",
        action=OnOff,
        default=False,
        help="put the controller in checksum mode (default: off)",
    )
    group.add_argument(
        "--algorithm",
        type=algorithm_name,
        action=GivenAlgorithm,
        default=DEFAULT_ALGORITHM,
        metavar="NAME",
        help=f"checksum algorithm: {', '.join(sorted(ALGORITHMS))}; a sim:// controller "
        "takes it too (default: the URL's ?algorithm= for sim://, else %(default)s)",
    )
    group.add_argument(
        "--baudrate",
        type=baud_rate,
        default=None,
        metavar="BAUD",
        help="serial speed (default: the URL's ?baudrate=, else 115200)",
    )
    group.add_argument(
        "--timeout",
        dest="timeout_s",
        type=reply_timeout,
        default=DEFAULT_REPLY_TIMEOUT_S,
        metavar="SECONDS",
        help=f"wait for a reply, per attempt, {MIN_TIMEOUT_S:g}–{MAX_TIMEOUT_S:g} "
        "(default: %(default)s)",
    )
    group.add_argument(
        "--retries",
        type=_retries,
        default=2,
        metavar="N",
        help=f"extra attempts of a query, 0–{MAX_RETRIES} (default: %(default)s)",
    )
    group.add_argument(
        "--boot-timeout",
        dest="boot_timeout_s",
        type=_optional_seconds,
        default=DEFAULT_BOOT_TIMEOUT_S,
        metavar="SECONDS",
        help="wait this long on connect for the controller to answer (a board "
        "that resets when its port opens boots for up to 2 s); 0: do not wait "
        "(default: %(default)s)",
    )
    from rovlink.cli.recording import add_record_options  # noqa: PLC0415 - as open_recorder

    add_record_options(parser)


def add_hearing_option(parser: argparse.ArgumentParser) -> None:
    """``--hear-other-lines``, for the tools that show the lock (web, monitor, the bridges)."""
    parser.add_argument(
        "--hear-other-lines",
        action="store_true",
        help="put the controller's debug output on (#debug1!, again after a reset), so that a "
        "#stop! from another line or a failsafe shows here as locked; the controller then "
        "writes a line of text for each change it makes, to every line (default: off)",
    )


async def hear_other_lines_if_asked(args: argparse.Namespace, client: AsyncClient) -> None:
    """With ``--hear-other-lines``, put the controller's debug output on (and again after a
    reset: :func:`rovlink.piloting.hearing.hear_other_lines`); else nothing."""
    if getattr(args, "hear_other_lines", False):
        from rovlink.piloting.hearing import hear_other_lines  # noqa: PLC0415

        await hear_other_lines(client)


def client_options(
    args: argparse.Namespace,
    *,
    keepalive_s: float | None = None,
    on_stray: StrayCallback | None = None,
    motion_timeout_s: float | None = None,
    reconnect: bool = False,
) -> ClientOptions:
    """The driver's settings from the parsed link options: the one place they meet.

    A value the driver refuses is a usage error.
    """
    from rovlink.client import ClientOptions  # noqa: PLC0415 - the driver loads when used

    recorder = session_recorder(args)
    try:
        return ClientOptions(
            timeout_s=args.timeout_s,
            retries=args.retries,
            checksum=args.checksum,
            algorithm=args.algorithm,
            keepalive_s=keepalive_s,
            on_stray=on_stray,
            boot_timeout_s=getattr(args, "boot_timeout_s", DEFAULT_BOOT_TIMEOUT_S),
            motion_timeout_s=motion_timeout_s,
            on_event=recorder.on_event if recorder is not None else None,
            reconnect=reconnect,
        )
    except ValueError as error:
        raise UsageError(str(error)) from None


def session_recorder(args: argparse.Namespace) -> Recorder | None:
    """The recorder of ``--record FILE`` (``None`` without it), started on first use and
    finished when the command ends (:func:`rovlink.cli.main` runs ``args.on_exit``)."""
    if not getattr(args, "record", None):
        from rovlink.cli.recording import refuse_rotation_without_record  # noqa: PLC0415

        refuse_rotation_without_record(args)
        return None
    recorder: Recorder | None = getattr(args, "recorder", None)
    if recorder is None:
        import time  # noqa: PLC0415

        from rovlink.cli.recording import (  # noqa: PLC0415
            discard_empty_recording,
            open_recorder,
            recorded_nothing,
            report_recording,
        )

        check_url(args)  # a malformed URL is refused before its recording's file is made
        program = f"rovlink {getattr(args, 'command', None) or ''}".strip()
        # Started before the driver connects, whose connect probe and mode frame go plain
        # (--checksum: its #crcon!, recorded with the mode change, switches after them).
        recorder = open_recorder(args, args.record, url=args.url, program=program, checksum=False)
        args.recorder = recorder
        started_s = time.monotonic()

        def finish() -> None:
            lost = _link_lost(getattr(args, "failure", None))
            if lost is not None:  # in the file too: read later, it must say why it ends
                from rovlink.client.events import LinkState  # noqa: PLC0415

                recorder.on_event(LinkState(time.monotonic(), "lost", str(lost)))
            recorder.close()
            if recorded_nothing(recorder):  # (the link did not open, or carried nothing)
                discard_empty_recording(recorder, program)
            else:
                report_recording(recorder, time.monotonic() - started_s)
            # (main() fails the command with it: a dive believed recorded was not)
            args.recording_failure = recorder.error

        on_exit = getattr(args, "on_exit", None)
        if on_exit is not None:
            on_exit.append(finish)
        else:  # run without main(): finish at exit at the latest
            import atexit  # noqa: PLC0415

            atexit.register(finish)
    return recorder


def _link_lost(failure: BaseException | None) -> BaseException | None:
    """The lost link that ended the command, if one did: ``failure`` or what it was raised
    from or while handling (a command says a lost link in its own words)."""
    from rovlink.client.errors import ConnectionLostError  # noqa: PLC0415

    seen: set[int] = set()
    while failure is not None and id(failure) not in seen:
        if isinstance(failure, ConnectionLostError):
            return failure
        seen.add(id(failure))
        failure = failure.__cause__ or failure.__context__
    return None


def recording_failure(args: argparse.Namespace) -> str | None:
    """Why the recording of ``--record FILE`` stopped (naming the file), if it did: all the
    session so far is written and made durable first, so a full disk shows here, while the
    command can still stop the robot before it fails. ``None`` without ``--record``."""
    recorder: Recorder | None = getattr(args, "recorder", None)
    return recorder.sync() if recorder is not None else None


def check_url(args: argparse.Namespace) -> None:
    """Refuse a malformed URL before anything is opened (a usage error naming it); for a
    ``sim://`` URL, have the simulated controller and the host use one checksum algorithm."""
    from rovlink.client import parse_url  # noqa: PLC0415

    try:
        parse_url(args.url, args.baudrate)
    except ValueError as error:
        raise UsageError(f"URL: {error}") from None
    agree_on_algorithm_with_simulator(args)


def agree_on_algorithm_with_simulator(args: argparse.Namespace) -> None:
    """For a simulated controller (``sim://``, or one behind ``fault://?inner=sim://…``),
    ``--algorithm NAME`` goes into its URL (``?algorithm=NAME``); without it, the host takes
    the algorithm the URL names, if it names one. Other URLs are left as they are."""
    found = _simulator_in(args.url)
    if found is None:
        return
    simulator, put_back = found
    agreed = _simulator_url_agreed(args, simulator)
    if agreed != simulator:
        args.url = put_back(agreed)


def names_simulator(url: str) -> bool:
    """Whether ``url`` leads to rovlink's simulator (``sim://``, or one behind ``fault://``).

    >>> names_simulator("sim://?seed=1"), names_simulator("fault://?inner=sim://&ber=1e-3")
    (True, True)
    >>> names_simulator("/dev/ttyUSB0")
    False
    """
    return _simulator_in(url) is not None


def _simulator_in(url: str) -> tuple[str, Callable[[str], str]] | None:
    """The ``sim://`` URL ``url`` leads to (itself, or a ``fault://`` URL's inner one) and how
    to put a changed one in its place; ``None`` for any other URL."""
    from rovlink.client import parse_url  # noqa: PLC0415

    handler = parse_url(url).handler
    if handler == "sim":
        return url, lambda changed: changed
    if handler == "fault":
        from rovlink.faults.settings import fault_url, parse_fault_url  # noqa: PLC0415

        inner, settings = parse_fault_url(url)
        if parse_url(inner).handler == "sim":
            return inner, lambda changed: fault_url(changed, settings)
    return None


def _simulator_url_agreed(args: argparse.Namespace, url: str) -> str:
    """``url`` (a ``sim://`` URL) with the algorithm asked for; or, none asked for, as it is,
    the host then taking the one it names."""
    from rovlink.sim.url import parse_sim_url, with_algorithm  # noqa: PLC0415

    if getattr(args, "algorithm_given", False):
        try:
            return with_algorithm(url, args.algorithm)
        except ValueError as error:
            raise UsageError(f"--algorithm {args.algorithm}: {error}") from None
    named = parse_sim_url(url).algorithm
    if named is not None:
        args.algorithm = named
    return url


def connection_failure(url: str, error: BaseException) -> CommandError:
    """One line for a port that could not be opened: the system's reason, said once.

    >>> str(connection_failure("/dev/null", OSError(25, "Inappropriate ioctl for device")))
    '/dev/null: not a serial port'
    >>> str(connection_failure("/dev/ttyUSB9", OSError(2, "[Errno 2] could not open port")))
    'cannot open /dev/ttyUSB9: No such file or directory'
    >>> from rovlink.client.errors import ConnectError
    >>> str(connection_failure("sim://", ConnectError("sim: more retries=N?", setting="retries")))
    'sim: more --retries N?'
    """
    import errno  # noqa: PLC0415

    from rovlink.client.errors import ConnectError  # noqa: PLC0415

    # The driver's words, unless they pass on pyserial's raw text ("[Errno 21] …: '/tmp'"); a
    # setting they ask to change (``retries=N``) is named as its option here (``--retries N``).
    if isinstance(error, ConnectError) and "[Errno" not in str(error):
        text = str(error)  # already one line in a user's words
        if error.setting is not None:
            option = "--" + error.setting.replace("_", "-")
            text = text.replace(f"{error.setting}=N", f"{option} N")
        return CommandError(text)
    if error_number(error) == errno.ENOTTY:
        return CommandError(f"{url}: not a serial port")
    return CommandError(f"cannot open {url}: {reason(error)}")


def ask(prompt: str) -> str | None:
    """The line typed after ``prompt``, or None when the input ends there (Ctrl-D): the
    command takes that as a no, never as a traceback."""
    try:
        return input(prompt)
    except EOFError:
        print()  # the prompt's line ends here, not in the message that follows
        return None


def confirmed(prompt: str, *, accept: tuple[str, ...] = ("yes",)) -> bool:
    """Whether the answer to ``prompt`` is one of ``accept`` (in any case, with spaces around);
    the end of the input is a no."""
    answer = ask(prompt)
    return answer is not None and answer.strip().lower() in accept


def log_warnings() -> None:
    """Show the library's warnings on stderr (a long-running command: dropped frames, suspected
    resets, a broker that refuses the login)."""
    # The driver logs what the user should know at WARNING and up; --verbose has already
    # configured DEBUG, which this leaves alone.
    import logging  # noqa: PLC0415 - not on the start-up path of decode

    logging.basicConfig(
        level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s: %(message)s"
    )


class _ShownLink:
    """A link that shows every byte it moves, as it moves them."""

    def __init__(self, link: Link, show: ShowBytes) -> None:
        self._link = link
        self._show = show
        self.description = link.description

    def read_available(self, timeout_s: float) -> bytes:
        data = self._link.read_available(timeout_s)
        if data:
            self._show("<<", data)
        return data

    def write(self, data: bytes) -> None:
        self._show(">>", data)
        self._link.write(data)

    def wake(self) -> None:
        self._link.wake()

    def close(self) -> None:
        self._link.close()


def _connect_showing_bytes(
    args: argparse.Namespace, options: ClientOptions, show: ShowBytes
) -> Client:
    from rovlink.client import Client, parse_url  # noqa: PLC0415
    from rovlink.client.links import open_link  # noqa: PLC0415

    link = _ShownLink(open_link(parse_url(args.url, args.baudrate)), show)
    try:
        return Client(link, options)
    except BaseException:
        link.close()
        raise


def connect(
    args: argparse.Namespace,
    *,
    keepalive_s: float | None = None,
    on_stray: StrayCallback | None = None,
    show_bytes: ShowBytes | None = None,
) -> Client:
    """A blocking client on ``args.url`` with the link options; failures are one line.

    ``show_bytes`` sees every byte written and read (the bytes exactly, not frames).
    """
    import rovlink.client  # noqa: PLC0415

    check_url(args)
    options = client_options(args, keepalive_s=keepalive_s, on_stray=on_stray)
    log_warnings()
    try:
        if show_bytes is not None:
            return _connect_showing_bytes(args, options, show_bytes)
        return rovlink.client.connect(args.url, baudrate=args.baudrate, options=options)
    except (ConnectionError, OSError) as error:
        raise connection_failure(args.url, error) from None
    except ValueError as error:
        raise UsageError(str(error)) from None


class _ClosingUnlessInterrupted:
    # A class rather than contextlib.contextmanager: contextlib is not imported at start-up.
    def __init__(self, client: Client) -> None:
        self._client = client

    def __enter__(self) -> Client:
        return self._client

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        if not isinstance(error, KeyboardInterrupt):
            self._client.close()


def closing_unless_interrupted(client: Client) -> _ClosingUnlessInterrupted:
    """Close ``client`` at the end, except after Ctrl-C: closing waits for the replies of the
    queries on the wire (up to the timeout), and Ctrl-C must end the command at once; the
    process is ending, and the system releases the port."""
    return _ClosingUnlessInterrupted(client)


def connect_async(args: argparse.Namespace) -> Callable[[StrayCallback], Awaitable[AsyncClient]]:
    """A function connecting an asyncio client on ``args.url`` with the link options (the
    console and monitor call it with their ``on_stray``); the options are checked now."""
    import rovlink.aio  # noqa: PLC0415

    check_url(args)
    client_options(args)
    log_warnings()

    def connect_with(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
        # No motion timeout (P23): a person sets a motion here and it holds until they change
        # it. The keep-alive runs on the tool's own event loop, so a tool that hangs stops
        # feeding the controller's link-loss watchdog (P17), which then stops the robot.
        # A lost link (an adapter unplugged and plugged back) is reopened, not the end.
        options = client_options(args, keepalive_s=1.0, on_stray=on_stray, reconnect=True)
        return rovlink.aio.connect(args.url, baudrate=args.baudrate, options=options)

    return connect_with
