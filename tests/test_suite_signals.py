"""The suite runs as a background job too: signals a shell's background job starts with ignored
are given back their default before any test starts a command."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

_REPOSITORY = Path(__file__).resolve().parent.parent


def test_the_suite_gives_back_sigint_and_sigquit_ignored_by_a_background_start() -> None:
    # Before, SIGQUIT stayed ignored: every test that ends a command with SIGQUIT waited for an
    # exit that never came when the suite ran as `pytest &`.
    shown = subprocess.run(
        [
            sys.executable,
            "-c",
            # (ignored as a background job starts ignoring them, before the conftest loads)
            "import signal; "
            "signal.signal(signal.SIGINT, signal.SIG_IGN); "
            "signal.signal(signal.SIGQUIT, signal.SIG_IGN); "
            "import tests.conftest; "
            "print(signal.getsignal(signal.SIGINT) is signal.SIG_IGN, "
            "signal.getsignal(signal.SIGQUIT) is signal.SIG_IGN)",
        ],
        cwd=_REPOSITORY,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    assert shown.stdout.split() == ["False", "False"]
