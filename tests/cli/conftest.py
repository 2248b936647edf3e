"""Running ``rovlink`` in-process: ``run_cli("send", "sim://", "qd")`` → status, stdout, stderr."""

from __future__ import annotations

import io
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from rovlink.cli import main
from rovlink.cli import monitor as cli_monitor
from tests.cli.silent_controller import SilentController


@dataclass(frozen=True)
class CliResult:
    """What a run of the command line returned and printed."""

    status: int
    out: str
    err: str


RunCli = Callable[..., CliResult]


class _TerminalInput(io.TextIOWrapper):
    """Standard input that says it is a terminal, so that a command asks on it."""

    def isatty(self) -> bool:
        return True


@pytest.fixture
def run_cli(capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> RunCli:
    """Run ``rovlink ARGS``; ``stdin=b"…"`` gives its standard input, ``tty=True`` makes that
    input a terminal (the prompts ask, and its end is Ctrl-D)."""

    def run(*argv: str, stdin: bytes = b"", tty: bool = False) -> CliResult:
        kind = _TerminalInput if tty else io.TextIOWrapper
        monkeypatch.setattr(sys, "stdin", kind(io.BytesIO(stdin)))
        capsys.readouterr()
        status = main(list(argv))
        captured = capsys.readouterr()
        return CliResult(status, captured.out, captured.err)

    return run


@pytest.fixture
def monitor_on_a_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    """``rovlink monitor`` runs as if its input and output were a terminal (it refuses to run
    without one), for tests of what it does after that check."""
    monkeypatch.setattr(cli_monitor, "missing_terminal", lambda: None)


@pytest.fixture
def silent() -> Iterator[SilentController]:
    """A controller that never answers (it records what it reads)."""
    controller = SilentController()
    yield controller
    controller.close()
