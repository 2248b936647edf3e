"""``rovlink monitor`` needs a terminal: without one it is refused before the link opens."""

from __future__ import annotations

import functools
import re
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


@pytest.mark.integration
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
        "rovlink monitor: needs a terminal for its dashboard and keys, but standard input, "
        "standard output and standard error are not a terminal; without one, read the sensors "
        "with "
        "'rovlink send URL qsa', or record the link with 'rovlink record URL -o FILE'\n"
    )
    assert not recording.exists()


def test_the_monitor_names_the_stream_that_is_not_a_terminal(run_cli: RunCli) -> None:
    result = run_cli("monitor", "sim://", tty=True)  # keys could come, but the output is a file
    assert result.status == 2
    assert "but standard output and standard error are not a terminal;" in result.err
    assert "standard input" not in result.err


@pytest.mark.integration
def test_the_monitor_with_its_standard_error_elsewhere_is_refused() -> None:
    # Before, with its keys and output on the terminal but standard error sent elsewhere
    # (2>monitor.log, 2>/dev/null), the dashboard (which textual draws on standard error) went
    # into the file: the screen stayed blank while the keys unlocked and drove the robot.
    with _listener() as server:
        url = f"socket://127.0.0.1:{server.getsockname()[1]}"
        terminal = Terminal("monitor", url)  # (its standard error a pipe)
        try:
            _, stderr = terminal.process.communicate(timeout=WAIT_S)
            assert not _connected(server)
        finally:
            terminal.close()
    assert terminal.process.returncode == 2
    assert "but standard error is not a terminal;" in stderr.decode()


def test_a_malformed_url_is_still_said_first(run_cli: RunCli) -> None:
    result = run_cli("monitor", "sim://?nosuch=1")
    assert result.status == 2
    assert "unknown sim option 'nosuch'" in result.err
    assert "terminal" not in result.err


@pytest.mark.integration
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
    terminal = Terminal("monitor", "sim://", env=ascii_locale, stderr_on_terminal=True)
    try:
        assert terminal.process.wait(timeout=WAIT_S) == 2
        assert terminal.wait_shown(b"LC_ALL=C.UTF-8\r\n")
        assert bytes(terminal.shown) == (
            b"rovlink monitor: the terminal's encoding, ascii, cannot show the dashboard's boxes "
            b"and arrows; run it in a UTF-8 locale, e.g. LC_ALL=C.UTF-8\r\n"
        )
        assert b"\\u25" not in terminal.shown
    finally:
        terminal.close()


def _plain(shown: bytes) -> bytes:
    """What was sent to the terminal, its control sequences (colours, moves) left out."""
    return re.sub(rb"\x1b\[[0-9;?]*[A-Za-z]", b"", shown)


def _redrawn_link_box_thrice(start: int, shown: bytes) -> bool:
    """Whether the link box ("last reading … s ago") was drawn three times since ``start``."""
    return shown[start:].count(b"last reading") >= 3


#: The titles of the boxes that do not change between polls, as drawn on their borders.
_IDLE_BOX_TITLES = (b"depth, cm", b"attitude", b"commanded, as last sent", b"\xe2\x94\x80 leak ")


@pytest.mark.integration
def test_an_idle_dashboard_draws_again_only_the_box_that_changed() -> None:
    # Before, every box was drawn again four times a second though nothing in it changed (a
    # border's subtitle set to what it was): 30 kB/s to the terminal, and CPU, at --rate 0.1,
    # a load on a slow link to the pilot's screen. Between polls only the link box changes
    # (its "last reading … s ago").
    terminal = Terminal("monitor", "sim://", "--rate", "0.1", stderr_on_terminal=True)
    try:
        assert terminal.wait_until(lambda shown: b"raw pressure 2" in _plain(shown))  # (polled)
        # Three redraws of the link box in a row with no other box among them (a start-up
        # redraw of the whole screen may come late on a slow machine: a few tries).
        redrawn_boxes: set[bytes] = set()
        for _ in range(5):
            start = len(terminal.shown)
            assert terminal.wait_until(functools.partial(_redrawn_link_box_thrice, start))
            idle = bytes(terminal.shown[start:])
            redrawn_boxes = {title for title in _IDLE_BOX_TITLES if title in idle}
            if not redrawn_boxes:
                break
        assert redrawn_boxes == set()
    finally:
        terminal.close()


#: What asks a terminal to report the mouse's buttons (X10, normal, button- and any-motion
#: tracking): once written, a click in the window reaches the program instead of the selection.
_MOUSE_REPORTING_ON = re.compile(rb"\x1b\[\?(?:9|1000|1002|1003)h")


@pytest.mark.integration
def test_the_dashboard_leaves_the_mouse_to_the_terminal() -> None:
    # Regression: the monitor turned mouse reporting on, and a press of the button on a footer
    # key ran it: the click that focuses the window, on "s start", unlocked the motors.
    terminal = Terminal("monitor", "sim://", stderr_on_terminal=True)
    try:
        assert terminal.wait_until(lambda shown: b"raw pressure 2" in _plain(shown))
        assert _MOUSE_REPORTING_ON.search(bytes(terminal.shown)) is None
        terminal.type("q")
        assert terminal.process.wait(WAIT_S) == 0
    finally:
        terminal.close()
