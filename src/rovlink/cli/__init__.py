"""The ``rovlink`` command line: one module per command, imported only when that command runs.

This module imports only the standard library's start-up modules (:mod:`argparse`, :mod:`os`,
:mod:`sys`, …), the package's version and its error types, and holds the table of commands
below, so that ``rovlink --version`` and ``rovlink decode`` start about as fast as Python
itself. Each command's module (``rovlink.cli.<name>``) has ``add_arguments(parser)`` and
``run(args) -> int``; the heavy libraries (pyserial, rich, textual, prompt_toolkit, the driver)
load inside ``run``.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys

import rovlink
from rovlink.cli.failure import CommandError, UsageError

# Not typing's: start-up is a measured figure.
TYPE_CHECKING = False

if TYPE_CHECKING:
    from collections.abc import Callable
    from typing import Any

__all__ = ["COMMANDS", "build_parser", "main", "plain_text"]

#: Every command and its one-line summary, in the order ``rovlink --help`` lists them.
COMMANDS: dict[str, str] = {
    "decode": "Decode a captured byte stream: one JSON object per line per event.",
    "reference": "Print the command reference (Markdown), as in docs/commands.md.",
    "sim": "Serve a simulated controller on a pseudo-terminal and/or a TCP port.",
    "send": "Send commands and print the decoded replies.",
    "demo": "A scripted dive: unlock, dive and hold, a square, every sensor, surface, lock.",
    "console": "Type commands and see the replies, with completion and history.",
    "monitor": "A live dashboard of depth, attitude, leak and link; keys drive the robot.",
    "record": "Record a link (listening, or as a tap between a program and the controller).",
    "replay": "Print a recording, or replay its commands to a controller and compare replies.",
    "plot": "Plot a recorded dive: depth and set-point, thrust, attitude, leak, link events.",
    "controller": "Run the controller on a board (pi, or sim) and serve its serial line.",
    "mavlink": "Serve the robot as a MAVLink vehicle (QGroundControl, MAVProxy, pymavlink).",
    "mqtt": "Put the robot on an MQTT broker: telemetry, state and events out, commands in.",
    "fleet": "A live table of every robot on an MQTT broker (online, depth, leak, link).",
    "check": "Check that a controller conforms to the protocol (pass/fail table, JUnit XML).",
    "fault": "A proxy that injects seeded bit errors, losses and delays into a controller's link.",
    "tune": "Depth-PID autotune: relay experiment, stated rule, gains on 0-99, verification.",
    "calibrate": "Two-point depth calibration: sdz and sdk from the surface and a known depth.",
    "web": "Serve the web ground station: gauges, charts, gamepad, STOP, in the browser.",
}

_DESCRIPTION = "Drive an underwater robot's low-level controller over its serial command protocol."
_EPILOG = """\
examples:
  rovlink sim                          serve a simulated controller on a pseudo-terminal
  rovlink send sim:// start "th 270 25" qsa stop
  rovlink monitor /dev/ttyUSB0 --checksum
  rovlink decode capture.bin --stats

'rovlink COMMAND --help' describes a command and its options."""

_EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it
#: Errors of a write that no command can do anything about (a full disk, a dead device): the
#: output given to the command line (``> /dev/full``) or a file it writes.
_OUTPUT_ERRNOS = frozenset({errno.ENOSPC, errno.EFBIG, errno.EIO, errno.EDQUOT})


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions and epilogs keep their line breaks (examples stay one per line).

    The width is found as :func:`shutil.get_terminal_size` finds it, without importing shutil
    (with its compression modules) on every start, help or not.
    """

    def __init__(
        self,
        prog: str,
        indent_increment: int = 2,
        max_help_position: int = 24,
        width: int | None = None,
    ) -> None:
        if width is None:
            width = _terminal_columns() - 2
        super().__init__(prog, indent_increment, max_help_position, width)

    # Descriptions are the commands' module docstrings, written for Sphinx as well: their
    # markup is turned into plain text as help is printed (only then: decode starts fast).
    def _fill_text(self, text: str, width: int, indent: str) -> str:
        return super()._fill_text(plain_text(text), width, indent)

    def _split_lines(self, text: str, width: int) -> list[str]:
        return super()._split_lines(plain_text(text), width)


def plain_text(text: str) -> str:
    """Help text without reStructuredText markup: roles give their target's name, literals
    are quoted as the help quotes commands.

    >>> plain_text("The script is :func:`run_dive`; see :class:`~rovlink.aio.AsyncClient`.")
    'The script is run_dive(); see AsyncClient.'
    >>> plain_text("It reads what ``rovlink mqtt`` publishes.")
    "It reads what 'rovlink mqtt' publishes."
    """
    import re  # noqa: PLC0415 - only as help is printed (argparse has loaded it anyway)

    def role(match: re.Match[str]) -> str:
        target = match["target"]
        name = target.rsplit(".", 1)[-1] if target.startswith("~") else target
        return name + ("()" if match["role"] in {"func", "meth"} else "")

    text = re.sub(r":(?:py:)?(?P<role>[a-z]+):`(?P<target>[^`]+)`", role, text)
    text = re.sub(r"``([^`]+)``", r"'\1'", text)
    return re.sub(r"`([^`]+)`", r"\1", text)


def _terminal_columns() -> int:
    import os  # noqa: PLC0415 - already loaded by the interpreter

    try:
        return int(os.environ["COLUMNS"])
    except (KeyError, ValueError):
        pass
    stdout = sys.__stdout__
    try:
        return os.get_terminal_size(stdout.fileno()).columns if stdout is not None else 80
    except (ValueError, OSError):
        return 80


def _chosen_command(argv: list[str]) -> str | None:
    """The command named in ``argv``: the first word that is not a root option."""
    for word in argv:
        if word == "--":
            return None
        if not word.startswith("-"):
            return word if word in COMMANDS else None
    return None


def build_parser(command: str | None = None, *, others: bool = True) -> argparse.ArgumentParser:
    """The parser of ``rovlink``; only ``command``'s own options are added (its module loads).

    ``others=False`` leaves the other commands out altogether (a parser each costs more than
    the rest of the parse): for a command line whose first word is ``command``, where every
    later word is the command's and no help lists the commands.
    """
    parser = argparse.ArgumentParser(
        prog="rovlink",
        description=_DESCRIPTION,
        epilog=_EPILOG,
        formatter_class=_Formatter,
    )
    # Every parser gets the formatter (and the subparsers their prog): argparse makes a
    # formatter for each argument it adds, and its default one imports shutil.
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug details to stderr")
    parser.add_argument("--version", action="version", version=f"rovlink {rovlink.__version__}")
    subparsers = parser.add_subparsers(
        dest="command", title="commands", metavar="COMMAND", prog="rovlink"
    )
    for name, summary in COMMANDS.items():
        if name != command:
            if not others:
                continue
            subparsers.add_parser(
                name, help=summary, description=summary, formatter_class=_Formatter
            )
            continue
        module = importlib.import_module(f"rovlink.cli.{name}")
        doc = (module.__doc__ or summary).strip()
        subparser = subparsers.add_parser(
            name,
            help=summary,
            description=doc,
            formatter_class=_Formatter,
            epilog=getattr(module, "EPILOG", None),
        )
        module.add_arguments(subparser)
        subparser.set_defaults(run=module.run, parser=subparser)
    return parser


#: Commands that never talk to a robot: the default end on SIGTERM suits them, and ``decode``
#: keeps its start-up (the signal module costs it a millisecond).
_NO_ROBOT = frozenset({"decode", "reference", "plot"})


def _nothing() -> None:
    pass


def _take_termination_as_ctrl_c() -> Callable[[], None]:
    """Have SIGTERM, SIGHUP and SIGQUIT (a service stopped, ``kill``, a terminal or an SSH
    session closed, the Ctrl-\\ key) end the command as Ctrl-C does: after ``#stop!`` where it
    may have moved the robot, with its recording finished; returns what puts the previous
    handlers back. Commands that serve (``sim``, ``controller``, ``record``, ``web``,
    ``fault``) put their own handlers over these, and asyncio commands take them on their event
    loop (``cli/async_run.py``). A signal
    ignored on entry (``nohup``) stays ignored."""
    import signal  # noqa: PLC0415 - not on the path of --help and --version

    def as_ctrl_c(signum: int, frame: object) -> None:
        # Raised as SIGINT, so that whoever handles Ctrl-C handles it: asyncio cancels its main
        # task, the console and the dashboard leave, a blocking command's main thread is
        # interrupted. Where SIGINT is ignored (a background job), as Ctrl-C's default.
        if signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, signal.SIG_DFL, None):
            raise KeyboardInterrupt
        signal.raise_signal(signal.SIGINT)

    previous: dict[int, Any] = {}
    try:
        for name in ("SIGTERM", "SIGHUP", "SIGQUIT"):
            number = getattr(signal, name, None)  # (no SIGHUP, SIGQUIT on Windows)
            if number is not None and signal.getsignal(number) is signal.SIG_DFL:
                previous[number] = signal.signal(number, as_ctrl_c)
    except ValueError:  # not the main thread (main() called by a program's thread)
        pass

    def restore() -> None:
        for number, handler in previous.items():
            signal.signal(number, handler)

    return restore


def main(argv: list[str] | None = None) -> int:
    """Run the ``rovlink`` command line on ``argv`` and return its exit status.

    0: done; 1: the command failed (the reason is one line on stderr); 2: a usage error;
    130: interrupted. Called without ``argv`` (as the console script, or ``python -m rovlink``)
    it reads ``sys.argv`` and exits with that status.
    """
    if argv is None:
        sys.exit(main(sys.argv[1:]))
    command = _chosen_command(argv)
    parser = build_parser(command, others=command is None or argv[0] != command)
    try:
        args, extras = parser.parse_known_args(argv)
        if extras:
            # Said by the command's parser, with its usage line (the root's would name
            # neither the command nor its options): "rovlink plot: error: …".
            getattr(args, "parser", parser).error(f"unrecognized arguments: {' '.join(extras)}")
    except SystemExit as exit_:  # --help, --version and usage errors
        return exit_.code if isinstance(exit_.code, int) else 2
    if args.command is None:
        parser.print_help()
        return 0
    if args.verbose:
        import logging  # noqa: PLC0415 - only when asked for

        logging.basicConfig(
            level=logging.DEBUG, format="%(asctime)s %(name)s %(levelname)s: %(message)s"
        )
    command_parser: argparse.ArgumentParser = args.parser
    # What a command opens that must outlive its client (a recording) is finished here, last.
    args.on_exit = []
    try:
        restore_signals = (
            _take_termination_as_ctrl_c() if args.command not in _NO_ROBOT else _nothing
        )
        try:
            status: int = args.run(args)
        except BaseException as error:
            args.failure = error  # (what ended it, for the finishers: a recording says so)
            raise
        finally:
            restore_signals()
            for finish in args.on_exit:
                finish()
    except UsageError as error:
        command_parser.print_usage(sys.stderr)
        print(_as_typed(f"{command_parser.prog}: error: {error}"), file=sys.stderr)
        return 2
    except CommandError as error:
        _say(f"{command_parser.prog}: {error}")
        return error.exit_status
    except KeyboardInterrupt:
        _say(f"{command_parser.prog}: interrupted")
        return _EXIT_INTERRUPTED
    except BrokenPipeError:
        # The reader of the output stopped early (``| head``): no error, as for any filter.
        # (Python would report the broken pipe again when it flushes stdout at exit.)
        sys.stdout = open(os.devnull, "w")  # noqa: SIM115 - stays open until exit
        return 0
    except OSError as error:
        if error.filename is not None or error.errno not in _OUTPUT_ERRNOS:
            raise
        print(f"{command_parser.prog}: cannot write the output: {error.strerror}", file=sys.stderr)
        return 1
    failure = getattr(args, "recording_failure", None)  # (set as its recording is finished)
    if failure is not None and status == 0:
        _say(f"{command_parser.prog}: {failure}")
        return 1
    return status


def _say(line: str) -> None:
    """A last line on stderr, if it can still be written: after a closed terminal (SIGHUP) it
    cannot, and the error of that write made the status 1 instead of the command's."""
    try:  # noqa: SIM105 - contextlib is not imported at start-up
        print(_as_typed(line), file=sys.stderr)
    except OSError:
        pass


def _as_typed(line: str) -> str:
    r"""``line`` with the bytes of a word that is not UTF-8 (a file name from a FAT stick) shown
    as ``\xNN``: Python holds each as a lone surrogate, which stderr (or a message's ``repr``)
    would show as ``\udcNN``.

    >>> _as_typed("cannot read \udcff.bin")
    'cannot read \\xff.bin'
    >>> _as_typed("unknown command 'q\\udcffd'")
    "unknown command 'q\\xffd'"
    """
    import re  # noqa: PLC0415 - loaded by argparse already; only as an error is said

    line = line.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    return re.sub(r"\\udc([89a-f][0-9a-f])", r"\\x\1", line)
