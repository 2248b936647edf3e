"""systemd's service watchdog: the board loop tells systemd after its control periods, so a
loop that hangs stops telling it (and systemd kills the process, ExecStopPost sets neutral)."""

from __future__ import annotations

import os
import socket
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from rovlink.board.pi.board import fake_bus_for, open_pi_board
from rovlink.board.server import BoardServer
from rovlink.board.service_notify import ServiceNotifier
from tests.board.rig import CONDITION_TIMEOUT_S, example_config, wait_until, with_controller

_INTERVAL_S = 0.02


@contextmanager
def _systemd_socket(tmp_path: Path) -> Iterator[socket.socket]:
    """The socket systemd would listen on for a service's notifications."""
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    listener.bind(str(tmp_path / "notify"))
    listener.setblocking(False)
    try:
        yield listener
    finally:
        listener.close()


def _received(listener: socket.socket) -> list[bytes]:
    messages = []
    while True:
        try:
            messages.append(listener.recv(100))
        except BlockingIOError:
            return messages


@pytest.mark.parametrize(
    ("environment", "expected_interval_s"),
    [
        ({"NOTIFY_SOCKET": "/run/n", "WATCHDOG_USEC": "5000000"}, 2.5),
        ({"NOTIFY_SOCKET": "@abstract", "WATCHDOG_USEC": "1000000", "WATCHDOG_PID": "self"}, 0.5),
        ({"NOTIFY_SOCKET": "/run/n"}, None),  # no WatchdogSec=: READY=1 only
        ({"NOTIFY_SOCKET": "/run/n", "WATCHDOG_USEC": "0"}, None),
        ({"NOTIFY_SOCKET": "/run/n", "WATCHDOG_USEC": "5000000", "WATCHDOG_PID": "1"}, None),
    ],
)
def test_the_watchdog_is_what_systemd_asks_for(
    environment: dict[str, str], expected_interval_s: float | None
) -> None:
    if environment.get("WATCHDOG_PID") == "self":
        environment["WATCHDOG_PID"] = str(os.getpid())
    notifier = ServiceNotifier.from_environment(environment)
    assert notifier is not None
    try:
        assert notifier.interval_s == expected_interval_s
    finally:
        notifier.close()


def test_not_under_systemd_nothing_is_told() -> None:
    assert ServiceNotifier.from_environment({"WATCHDOG_USEC": "5000000"}) is None


def test_without_a_watchdog_only_ready_is_told(tmp_path: Path) -> None:
    with _systemd_socket(tmp_path) as listener:
        notifier = ServiceNotifier(str(tmp_path / "notify"), interval_s=None)
        try:
            notifier.ready()
            for period in range(100):
                notifier.pet(period * 0.01)
        finally:
            notifier.close()
        assert _received(listener) == [b"READY=1"]


def test_the_watchdog_is_told_at_most_every_half_of_its_time(tmp_path: Path) -> None:
    with _systemd_socket(tmp_path) as listener:
        watchdog = ServiceNotifier(str(tmp_path / "notify"), interval_s=0.5)
        try:
            watchdog.ready()
            for period in range(100):  # one second of 10 ms control periods
                watchdog.pet(period * 0.01)
        finally:
            watchdog.close()
        assert _received(listener) == [b"READY=1", b"WATCHDOG=1", b"WATCHDOG=1"]


def test_a_control_loop_that_hangs_stops_telling_systemd(tmp_path: Path) -> None:
    from gpiozero.pins.mock import MockFactory

    config = with_controller(example_config(imu={"sensor": "none"}), watchdog_s=2.0)
    pins = MockFactory()
    board = open_pi_board(config, bus=fake_bus_for(config), pin_factory=pins)
    with _systemd_socket(tmp_path) as listener:
        watchdog = ServiceNotifier(str(tmp_path / "notify"), _INTERVAL_S)
        server = BoardServer(config.controller, board, service_notifier=watchdog)
        stop = threading.Event()
        hang = threading.Event()
        hung = threading.Event()
        tick = server.controller.tick

        def tick_that_may_hang() -> None:
            if hang.is_set():
                hung.set()
                stop.wait()  # a bug that loops for ever (until the test ends)
            tick()

        server.controller.tick = tick_that_may_hang  # type: ignore[method-assign]
        thread = threading.Thread(target=server.serve, args=(stop.is_set,), daemon=True)
        thread.start()
        try:
            told: list[bytes] = []
            assert wait_until(lambda: len(told.__iadd__(_received(listener))) >= 3)
            assert set(told) == {b"WATCHDOG=1"}
            hang.set()
            assert hung.wait(5)
            _received(listener)  # (told before it hung)
            # Ten of the watchdog's intervals (systemd's silence is two) with the loop stuck:
            # nothing is told.
            threading.Event().wait(10 * _INTERVAL_S)
            assert _received(listener) == []
        finally:
            stop.set()
            thread.join(10)
            server.close()
            watchdog.close()
            pins.close()


def test_a_notification_systemd_does_not_take_never_holds_the_control_loop(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    # Nobody reads the socket: once its queue is full, a blocking send waited for good, in the
    # control loop, where the thrusters are set.
    with _systemd_socket(tmp_path):
        notifier = ServiceNotifier(str(tmp_path / "notify"), interval_s=1.0)
        periods_done = threading.Event()

        def control_periods() -> None:
            for period in range(5000):  # far more than the socket's queue holds
                notifier.pet(float(period))
            periods_done.set()

        threading.Thread(target=control_periods, daemon=True).start()
        try:
            assert periods_done.wait(CONDITION_TIMEOUT_S), "a notification held the loop"
        finally:
            notifier.close()  # (a send still waiting fails now)
    errors = [record for record in caplog.records if "cannot notify systemd" in record.message]
    assert len(errors) == 1  # said once, not once a period
