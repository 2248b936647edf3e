"""Type commands (qd, th 270 25, mvs -50, #qd!) and see the replies; Ctrl-X stops the robot.

Tab completes names and shows each argument's range; 'help' lists every command; 'quit' or
Ctrl-D leaves, sending #stop! first unless the robot is locked as last sent.
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import sys
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, NoTerminalError, UsageError, is_terminal, reason

if TYPE_CHECKING:
    from pathlib import Path

    from rovlink.aio import AsyncClient
    from rovlink.client.options import StrayCallback

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink console                      on the simulator
  rovlink console /dev/ttyUSB0 --checksum --history ~/dive.history"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``console``'s options."""
    link_options.add_link_options(parser)
    parser.add_argument(
        "--history",
        type=link_options.file_name,
        metavar="FILE",
        help="history file (default: in the user's state directory)",
    )


def _check_history(path: Path, *, make_directory: bool) -> None:
    """Open the history file for appending now: prompt_toolkit writes it from its own thread,
    where a failure is a traceback and a console that hangs.

    Only the default file's directory is made: a missing directory in a name the user typed
    is a typing mistake, refused as ``--record`` refuses it.
    """
    try:
        if make_directory:
            path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("ab"):
            pass
    except OSError as error:
        raise CommandError(f"cannot keep the history in {path}: {reason(error)}") from None


def run(args: argparse.Namespace) -> int:
    """Run the console until the user leaves."""
    from pathlib import Path  # noqa: PLC0415

    from rovlink.cli.async_run import run_async  # noqa: PLC0415 - keep asyncio off other commands

    with needs_extra("console"):
        from rovlink.console.app import (  # noqa: PLC0415
            LinesFailedError,
            RefusedLineError,
            StopUnsentError,
            run_console,
        )
        from rovlink.console.history import default_history_path  # noqa: PLC0415
        from rovlink.console.script_input import script_input  # noqa: PLC0415

    link_options.check_url(args)  # (a malformed URL is said first, as by every command)
    from_terminal = is_terminal(sys.stdin)
    if from_terminal and not is_terminal(sys.stdout):
        # Typed into, its prompt, the replies and the toolbar would go to the file or the pipe
        # (through tee, in pieces): the lines typed, start and th among them, would run unseen.
        raise NoTerminalError(
            "typed into, its prompt and replies need a terminal, but standard output is not "
            "one: the lines typed would run unseen; to keep the session, use --record FILE "
            "(lines read from a file may go to one: rovlink console URL < lines.txt > out.txt)"
        )
    open_link = link_options.connect_async(args)  # (after: a --record file is not made)

    async def connect(on_stray: StrayCallback) -> AsyncClient:
        # Only a failure here is one to open the port: an OSError later is the terminal's.
        try:
            return await open_link(on_stray)
        except (ConnectionError, OSError) as error:
            raise _ConnectError(error) from None

    history: Path | None
    if args.history:
        history = Path(args.history)
        _check_history(history, make_directory=False)
    else:
        history = default_history_path()
        try:
            _check_history(history, make_directory=True)
        except CommandError as error:
            # A convenience, not a reason to keep a pilot from the robot (a read-only home, a
            # service user's home that is not there): this session's history only.
            print(f"rovlink console: {error}; kept for this session only", file=sys.stderr)
            history = None
    try:
        with contextlib.nullcontext() if from_terminal else script_input(sys.stdin):
            run_async(
                run_console(
                    connect,
                    algorithm=args.algorithm,
                    history_path=history,
                    # Lines read from a file or a pipe all run, in order, to the last.
                    from_terminal=from_terminal,
                    # (Its output to a file or a pipe is then what went out and came back alone:
                    # the console's own remarks go to stderr.)
                    notices=lambda text: print(
                        f"rovlink console: {text}", file=sys.stderr, flush=True
                    ),
                )
            )
    except (RefusedLineError, LinesFailedError) as error:
        raise CommandError(str(error)) from None
    except StopUnsentError:
        # Said already, where the console says it (its transcript, or stderr under a script):
        # a script learns it from the status, as from any failure.
        return 1
    except ValueError as error:
        raise UsageError(str(error)) from None
    except _ConnectError as failed:
        raise link_options.connection_failure(args.url, failed.error) from None
    except OSError as error:
        if error.errno != errno.EIO:
            raise
        # The terminal hung up (its window closed): #stop! went on the way out, as for Ctrl-C.
        raise KeyboardInterrupt from None
    return 0


class _ConnectError(Exception):
    """The port could not be opened (``error`` says why)."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error
