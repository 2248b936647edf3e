"""``rovlink send`` to a pseudo-terminal that is a terminal window's: one line saying whose it
is, and a non-zero exit (nothing is written into the window)."""

from __future__ import annotations

import sys
from collections.abc import Iterator

import pytest

from tests.cli.conftest import RunCli
from tests.terminals import TerminalWindow, refusal

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(not sys.platform.startswith("linux"), reason="Linux's /proc"),
]


@pytest.fixture
def window() -> Iterator[TerminalWindow]:
    opened = TerminalWindow()
    yield opened
    opened.close()


def test_the_command_line_says_whose_terminal_it_is(
    window: TerminalWindow, run_cli: RunCli
) -> None:
    result = run_cli("send", window.path, "qd")
    assert result.status != 0
    assert result.err.strip().splitlines() == [f"rovlink send: {refusal(window)}"], result.err
    assert window.shown() == b""
