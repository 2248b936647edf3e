"""The in-process simulated port behind the host driver's ``sim://``."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
import serial

from rovlink.sim import SimulatedPort, open_port


def _wait_for(condition: object, timeout_s: float = 5.0) -> None:
    assert callable(condition)
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail("condition not met in time")
        time.sleep(0.01)


def test_a_query_is_answered_when_write_returns() -> None:
    with open_port(seed=1, manual=True, timeout=0) as port:
        assert port.write(b"#qd!") == 4
        assert port.in_waiting == len(b"$qd.0!")
        assert port.read(100) == b"$qd.0!"


def test_read_returns_at_most_size_bytes_and_keeps_the_rest() -> None:
    with open_port(seed=1, manual=True, timeout=0) as port:
        port.write(b"#q.l!")
        assert port.read(3) == b"$q."
        assert port.read(100) == b"l.0!"


def test_read_times_out_with_nothing_to_read() -> None:
    with open_port(seed=1, manual=True, timeout=0.05) as port:
        started = time.monotonic()
        assert port.read(10) == b""
        assert time.monotonic() - started >= 0.04


def test_reset_input_buffer_discards_replies() -> None:
    with open_port(seed=1, manual=True, timeout=0) as port:
        port.write(b"#qd!#qr!")
        port.reset_input_buffer()
        assert port.in_waiting == 0


def test_a_blocked_read_wakes_up_when_a_reply_arrives() -> None:
    with open_port(seed=1, manual=True, timeout=None) as port:
        result: list[bytes] = []
        reader = threading.Thread(target=lambda: result.append(port.read(100)))
        reader.start()
        time.sleep(0.05)  # let the reader block; the test holds either way
        port.write(b"#q.l!")
        reader.join(timeout=5)
        assert result == [b"$q.l.0!"]


def test_close_stops_reads_and_writes() -> None:
    port = open_port(seed=1, timeout=0.1)
    port.close()
    assert not port.is_open
    with pytest.raises(serial.SerialException):
        port.write(b"#qd!")
    with pytest.raises(serial.SerialException):
        port.read()
    port.close()  # twice is harmless


def test_close_wakes_a_blocked_reader() -> None:
    port = open_port(seed=1, manual=True, timeout=None)
    errors: list[BaseException] = []

    def read() -> None:
        try:
            port.read()
        except serial.SerialException as error:
            errors.append(error)

    reader = threading.Thread(target=read)
    reader.start()
    time.sleep(0.05)
    port.close()
    reader.join(timeout=5)
    assert not reader.is_alive()
    assert len(errors) == 1


def test_a_failing_simulation_closes_the_port_saying_why() -> None:
    port = open_port(seed=1, realtime=False, timeout=0.05)

    def fail() -> None:
        raise RuntimeError("a scenario's bug")

    with port.lock:  # (an unpaced simulation may be past any fixed time already)
        fails_at_s = port.robot.time_s + 1.0
        port.robot.schedule(fails_at_s, fail)
    # Before, the thread died and the port kept answering from a robot frozen in time.
    _wait_for(lambda: not port.is_open)
    with pytest.raises(serial.SerialException, match="simulation stopped: RuntimeError: a sce"):
        port.write(b"#qd!")
    with pytest.raises(serial.SerialException, match="simulation stopped"):
        port.read()
    # It stopped at the failing step, in time.
    assert port.robot.time_s == pytest.approx(fails_at_s, abs=port.robot.tick_s)
    port.close()


def test_the_realtime_thread_advances_simulated_time() -> None:
    started_wall = time.monotonic()
    with open_port(seed=1, timeout=0.1) as port:
        _wait_for(lambda: port.robot.time_s >= 0.3)
        simulated_s = port.robot.time_s
        # Real time: a late thread catches up, but the simulation never runs ahead of the wall
        # clock (a bound measured from the start, which no amount of load can break).
        assert time.monotonic() - started_wall >= simulated_s


def test_fast_mode_runs_far_ahead_of_the_wall_clock() -> None:
    with open_port(seed=1, realtime=False, timeout=0.1) as port:
        started = time.monotonic()
        _wait_for(lambda: port.robot.time_s >= 30.0)
        assert time.monotonic() - started < 10.0


def test_the_robot_dives_through_the_port() -> None:
    with open_port(seed=2, manual=True, timeout=0) as port:
        port.write(b"#start!#mvd.100!")
        for _ in range(40):  # 20 s, with a query every 0.5 s to keep the link alive
            port.advance(0.5)
            port.write(b"#qd!")
        replies = port.read(10_000).split(b"!")
        assert replies[-2] in {b"$qd.%d" % depth for depth in range(94, 107)}
        assert port.vehicle.depth_m == pytest.approx(1.0, abs=0.05)
        assert not port.controller.locked


def test_leak_at_injects_a_pulse_at_that_simulated_time() -> None:
    with open_port(seed=1, leak_at_s=1.0, manual=True, timeout=0) as port:
        port.advance(0.9)
        port.write(b"#q.l!")
        assert port.read(100) == b"$q.l.0!"
        port.advance(0.2)
        port.write(b"#q.l!")
        assert port.read(100) == b"$q.l.1!"


def test_config_file_is_applied(tmp_path: Path) -> None:
    config = tmp_path / "robot.toml"
    config.write_text("[depth]\nzero_raw = 10\n\n[vehicle]\nnet_buoyancy_n = 3.0\n")
    with open_port(seed=1, config=config, manual=True, timeout=0) as port:
        assert port.controller.state().depth_zero_raw == 10
        assert port.vehicle.net_buoyancy_n == 3.0


def test_port_is_a_simulated_port() -> None:
    with open_port(seed=1, manual=True) as port:
        assert isinstance(port, SimulatedPort)
        port.start()
        with pytest.raises(RuntimeError, match="already running"):
            port.start()
