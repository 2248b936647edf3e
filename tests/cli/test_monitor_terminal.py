"""``rovlink monitor`` needs a terminal: without one it is refused before the link opens."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.cli.conftest import RunCli
from tests.terminals import WAIT_S, Terminal


def _listener() -> socket.socket:
    """A TCP port that would take the monitor's connection (it must not come)."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0)
    return server


def _connected(server: socket.socket) -> bool:
    try:
        connection, _ = server.accept()
    except BlockingIOError:
        return False
    connection.close()
    return True


def test_the_monitor_without_a_terminal_is_refused_before_the_link_opens(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # Regression: run from a script, it drew escape sequences to its output until killed, and
    # no key (not even space, the stop) could reach it.
    recording = tmp_path / "dive.jsonl"
    with _listener() as server:
        url = f"socket://127.0.0.1:{server.getsockname()[1]}"
        result = run_cli("monitor", url, "--record", str(recording))
        assert not _connected(server)
    assert result.status == 2
    assert result.out == ""
    assert result.err == (
        "rovlink monitor: needs a terminal for its dashboard and keys, but standard input and "
        "standard output are not a terminal; without one, read the sensors with "
        "'rovlink send URL qsa', or record the link with 'rovlink record URL -o FILE'\n"
    )
    assert not recording.exists()


def test_the_monitor_names_the_stream_that_is_not_a_terminal(run_cli: RunCli) -> None:
    result = run_cli("monitor", "sim://", tty=True)  # keys could come, but the output is a file
    assert result.status == 2
    assert "but standard output is not a terminal;" in result.err
    assert "standard input" not in result.err


def test_a_malformed_url_is_still_said_first(run_cli: RunCli) -> None:
    result = run_cli("monitor", "sim://?nosuch=1")
    assert result.status == 2
    assert "unknown sim option 'nosuch'" in result.err
    assert "terminal" not in result.err


@pytest.mark.timeout(30)
def test_the_monitor_with_its_output_to_a_file_ends_at_once(tmp_path: Path) -> None:
    output = tmp_path / "monitor.out"
    with output.open("wb") as stdout:
        finished = subprocess.run(
            [sys.executable, "-m", "rovlink", "monitor", "sim://"],
            stdin=subprocess.DEVNULL,
            stdout=stdout,
            stderr=subprocess.PIPE,
            timeout=20,  # (before the fix: drawing until killed)
            check=False,
        )
    assert finished.returncode == 2
    assert output.read_bytes() == b""  # not one escape sequence
    assert finished.stderr.decode().startswith("rovlink monitor: needs a terminal")


@pytest.mark.integration
def test_on_a_terminal_whose_encoding_cannot_draw_it_the_monitor_is_refused() -> None:
    # Before, in a locale that is not UTF-8 every box and arrow of the dashboard came out as an
    # escape ("\\u256d\\u2500 depth, cm \\u2500…"), over the whole screen.
    ascii_locale = {"LC_ALL": "C", "PYTHONCOERCECLOCALE": "0", "PYTHONUTF8": "0"}
    terminal = Terminal("monitor", "sim://", env=ascii_locale)
    try:
        _, stderr = terminal.process.communicate(timeout=WAIT_S)
        assert terminal.process.returncode == 2
        assert stderr.decode() == (
            "rovlink monitor: the terminal's encoding, ascii, cannot show the dashboard's boxes "
            "and arrows; run it in a UTF-8 locale, e.g. LC_ALL=C.UTF-8\n"
        )
        assert b"\\u25" not in terminal.shown
    finally:
        terminal.close()
