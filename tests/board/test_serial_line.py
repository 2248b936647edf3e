"""A serial device served by the controller's lines that goes away (a USB adapter unplugged, the
other end of a pseudo-terminal closed) and comes back."""

from __future__ import annotations

import os
import time
import tty
from collections.abc import Callable
from pathlib import Path

import pytest

from rovlink.controller import lines as lines_module
from rovlink.controller.lines import Line, Lines, SerialDeviceLine

pytestmark = pytest.mark.integration


def _pty() -> tuple[int, str]:
    """A pseudo-terminal: its master side, and the path of its terminal side (closed here)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    os.set_blocking(master, False)
    return master, path


def _wait_for(lines: Lines, condition: Callable[[], bool], timeout_s: float = 3.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        lines.wait(0.02)
        if condition():
            return True
    return False


def test_a_serial_device_that_goes_away_is_let_go_and_opened_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(lines_module, "SERIAL_REOPEN_S", 0.1)
    received = bytearray()

    def on_bytes(line: Line, data: bytes) -> None:
        received.extend(data)

    device = tmp_path / "ttyROV"  # as a udev name points at whichever node the adapter gets
    master, path = _pty()
    device.symlink_to(path)
    lines = Lines(on_bytes, busy_message=b"")
    try:
        lines.open_serial(str(device), 115200)
        os.write(master, b"#qd!")
        assert _wait_for(lines, lambda: received == b"#qd!")
        os.close(master)  # the device goes away: its descriptor reads as hung up from now on
        # and udev takes its name away (else the next terminal opened on this machine, which
        # may get the same /dev/pts number, would be opened as the device come back)
        device.unlink()
        assert _wait_for(lines, lambda: not lines.lines)
        # Gone, it is not spun on: a wait waits (before, each returned at once, at 100 % CPU).
        started = time.process_time()
        for _ in range(10):
            lines.wait(0.02)
        assert time.process_time() - started < 0.1
        master, path = _pty()  # plugged in again
        device.symlink_to(path)
        assert _wait_for(lines, lambda: len(lines.lines) == 1)
        assert isinstance(lines.lines[0], SerialDeviceLine)
        os.write(master, b"#qr!")
        assert _wait_for(lines, lambda: received == b"#qd!#qr!")
        lines.send(lines.lines[0], b"$qr.20!")
        time.sleep(0.05)
        assert os.read(master, 100) == b"$qr.20!"
    finally:
        lines.close()
        os.close(master)


def test_a_serial_device_found_gone_by_a_write_is_opened_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The controller writes on its own (a failsafe's debug line, a reply) and may meet the
    # unplugged adapter on a write before a read: it must come back all the same.
    monkeypatch.setattr(lines_module, "SERIAL_REOPEN_S", 0.1)
    received = bytearray()

    def on_bytes(line: Line, data: bytes) -> None:
        received.extend(data)

    device = tmp_path / "ttyROV"
    master, path = _pty()
    device.symlink_to(path)
    lines = Lines(on_bytes, busy_message=b"")
    try:
        lines.open_serial(str(device), 115200)
        os.close(master)  # unplugged
        device.unlink()
        lines.send(lines.lines[0], b"failsafe: no valid frame for 2 s\r\n")  # fails: EIO
        assert not lines.lines
        master, path = _pty()  # plugged in again
        device.symlink_to(path)
        assert _wait_for(lines, lambda: len(lines.lines) == 1)
        os.write(master, b"#qd!")
        assert _wait_for(lines, lambda: received == b"#qd!")
    finally:
        lines.close()
        os.close(master)
