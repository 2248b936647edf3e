"""A serial device served by the controller's lines that goes away (a USB adapter unplugged, the
other end of a pseudo-terminal closed) and comes back."""

from __future__ import annotations

import os
import select
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from rovlink.controller import lines as lines_module
from rovlink.controller.lines import Line, Lines, SerialDeviceLine
from tests.controller.controller_rig import make_rig

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


def _read_until(master: int, wanted: bytes, timeout_s: float = 3.0) -> bytes:
    """What the far end of a line reads, until ``wanted`` has come or the timeout."""
    data = b""
    deadline = time.monotonic() + timeout_s
    while wanted not in data and time.monotonic() < deadline:
        ready, _, _ = select.select([master], [], [], max(0.0, deadline - time.monotonic()))
        if ready:
            data += os.read(master, 100)
    return data


class _UsbAdapter:
    """A serial device under a name of its own, as udev gives an adapter, that can be unplugged
    and plugged in again; :attr:`master` is the far end of the line."""

    def __init__(self, name: Path) -> None:
        self.name = name
        self.master = -1
        self.plug_in()

    def plug_in(self) -> None:
        self.master, path = _pty()
        self.name.symlink_to(path)

    def unplug(self) -> None:
        # Its descriptor reads as hung up from now on, and udev takes its name away (else the
        # next terminal opened on this machine, which may get the same /dev/pts number, would
        # be opened as the device come back).
        os.close(self.master)
        self.master = -1
        self.name.unlink()

    def close(self) -> None:
        if self.master >= 0:
            os.close(self.master)


@pytest.fixture
def adapter(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[_UsbAdapter]:
    monkeypatch.setattr(lines_module, "SERIAL_REOPEN_S", 0.1)
    adapter = _UsbAdapter(tmp_path / "ttyROV")
    yield adapter
    adapter.close()


@pytest.fixture
def received() -> bytearray:
    """What the controller's lines read, in order."""
    return bytearray()


@pytest.fixture
def lines(adapter: _UsbAdapter, received: bytearray) -> Iterator[Lines]:
    """The controller's lines, serving ``adapter``'s device by its name."""

    def on_bytes(line: Line, data: bytes) -> None:
        received.extend(data)

    lines = Lines(on_bytes, busy_message=b"")
    try:
        lines.open_serial(str(adapter.name), 115200)
        yield lines
    finally:
        lines.close()


def test_a_serial_device_that_goes_away_is_let_go_and_opened_again(
    adapter: _UsbAdapter, lines: Lines, received: bytearray
) -> None:
    os.write(adapter.master, b"#qd!")
    assert _wait_for(lines, lambda: received == b"#qd!")
    adapter.unplug()
    assert _wait_for(lines, lambda: not lines.lines)
    # Gone, it is not spun on: a wait waits (before, each returned at once, at 100 % CPU).
    started = time.process_time()
    for _ in range(10):
        lines.wait(0.02)
    assert time.process_time() - started < 0.1
    adapter.plug_in()
    assert _wait_for(lines, lambda: len(lines.lines) == 1)
    assert isinstance(lines.lines[0], SerialDeviceLine)
    os.write(adapter.master, b"#qr!")
    assert _wait_for(lines, lambda: received == b"#qd!#qr!")
    lines.send(lines.lines[0], b"$qr.20!")
    assert _read_until(adapter.master, b"$qr.20!") == b"$qr.20!"


def test_a_serial_device_found_gone_by_a_write_is_opened_again(
    adapter: _UsbAdapter, lines: Lines, received: bytearray
) -> None:
    # The controller writes on its own (a failsafe's debug line, a reply) and may meet the
    # unplugged adapter on a write before a read: it must come back all the same.
    adapter.unplug()
    lines.send(lines.lines[0], b"failsafe: no valid frame for 2 s\r\n")  # fails: EIO
    assert not lines.lines
    adapter.plug_in()
    assert _wait_for(lines, lambda: len(lines.lines) == 1)
    os.write(adapter.master, b"#qd!")
    assert _wait_for(lines, lambda: received == b"#qd!")


def test_a_robot_driven_over_a_serial_device_that_is_unplugged_stops_at_once(
    adapter: _UsbAdapter,
) -> None:
    # The cable pulled (the USB adapter gone) while it drives: the controller's lines let the
    # device go and say so as they do for a TCP client that closed, so the robot stops at once,
    # not a watchdog later (here off) nor ever.
    rig = make_rig(watchdog_s=0.0)
    lines = Lines(
        lambda line, data: rig.controller.receive(data, line),
        busy_message=b"",
        on_close=rig.controller.forget_line,
    )
    try:
        lines.open_serial(str(adapter.name), 115200)
        os.write(adapter.master, b"#start!#th.0.100!")
        assert _wait_for(lines, lambda: rig.controller.state().power_percent == 100)
        adapter.unplug()
        assert _wait_for(lines, lambda: not lines.lines)
        state = rig.controller.state()
        assert state.locked
        assert state.power_percent == 0
    finally:
        lines.close()
