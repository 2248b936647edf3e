"""Every driver method against the simulated controller in this process (``sim://``)."""

from __future__ import annotations

import asyncio
from collections.abc import Callable
from pathlib import Path

import pytest

import rovlink
import rovlink.aio
from rovlink.aio.client import DEFAULT_MAX_IN_FLIGHT
from rovlink.client import Client, ClientOptions
from rovlink.client.links import PortLink
from rovlink.controller import ControllerConfig, ControllerState
from rovlink.protocol import Response, VerticalMode
from rovlink.sim import SimConfig, SimulatedPort, open_port
from tests.client.conftest import REPLY_TIMEOUT_S, wait_until
from tests.client.sim_scenario import DebugLines, check_sensors, run_every_method


def _port(client: object) -> SimulatedPort:
    port = client._link.port  # type: ignore[attr-defined]
    assert isinstance(port, SimulatedPort)
    return port


def _state_of(client: object) -> Callable[[], ControllerState]:
    port = _port(client)

    def state() -> ControllerState:
        with port.lock:
            return port.controller.state()

    return state


def test_every_method_through_the_controllers_debug_text() -> None:
    debug = DebugLines()
    with rovlink.connect(
        "sim://?seed=7", keepalive=None, on_stray=debug, timeout=REPLY_TIMEOUT_S
    ) as rov:
        run_every_method(rov, debug)


def test_every_method_of_the_blocking_client() -> None:
    debug = DebugLines()
    with rovlink.connect(
        "sim://?seed=1", keepalive=None, on_stray=debug, timeout=REPLY_TIMEOUT_S
    ) as rov:
        state = _state_of(rov)
        rov.set_debug(True)
        assert state().debug_enabled
        rov.set_max_pwm(200)
        rov.set_depth_pid(p=11, i=2, d=3)
        assert (state().max_pwm, state().gains) == (200, (11, 2, 3))
        rov.start()
        assert not state().locked
        rov.set_direct_mode(True)
        rov.set_vertical_thrust(-40)
        assert (state().vertical_mode, state().vertical_thrust_percent) == (
            VerticalMode.DIRECT,
            -40,
        )
        rov.set_direct_mode(False)
        rov.hold_depth(150)
        assert (state().vertical_mode, state().target_depth_cm) == (VerticalMode.DEPTH, 150)
        rov.move(270, 25)
        assert (state().direction_deg, state().power_percent) == (270, 25)
        rov.claw_open()
        debug.expect("claw opening")
        rov.claw_close()
        debug.expect("claw closing")
        reading = rov.sensors()
        check_sensors(reading)
        assert isinstance(rov.depth_cm(), int)
        assert 0 <= rov.pressure_raw() <= 1024
        assert rov.leak_detected() is False
        assert -90 <= rov.roll_deg() <= 90
        assert -90 <= rov.pitch_deg() <= 90
        assert 0 <= rov.heading_deg() <= 360
        rov.set_depth_zero(30)
        rov.set_depth_scale(900)
        assert (state().depth_zero_raw, state().depth_k) == (30, 900)
        rov.reset_leak()
        debug.expect("leak latch reset")
        rov.stop()
        assert state().locked
        assert state().power_percent == 0
        (reply,) = rov.send_raw("#qhe!")
        assert reply.name == "qhe"
        rov.set_debug(False)
        assert not state().debug_enabled
        counters = rov.counters
        assert (counters.timeouts, counters.retries, counters.bad_frames) == (0, 0, 0)


def test_checksum_mode_both_ways_with_the_simulator() -> None:
    with rovlink.connect(
        "sim://?seed=2", keepalive=None, checksum=True, timeout=REPLY_TIMEOUT_S
    ) as rov:
        state = _state_of(rov)
        assert state().checksum_enabled
        check_sensors(rov.sensors())
        rov.set_max_pwm(100)  # a checksummed set command the controller accepts
        assert state().max_pwm == 100
        rov.set_checksum(False)
        assert not state().checksum_enabled
        check_sensors(rov.sensors())
        rov.set_checksum(True)
        assert rov.depth_cm() >= 0
        assert rov.counters.checksum_errors == 0


@pytest.mark.parametrize("algorithm", ["xor", "sum8"])
def test_a_controller_with_another_checksum_algorithm(tmp_path: Path, algorithm: str) -> None:
    config = tmp_path / "controller.toml"
    config.write_text(f'[controller]\nchecksum_algorithm = "{algorithm}"\n')
    url = f"sim://?config={config}"
    with rovlink.connect(
        url, keepalive=None, checksum=True, algorithm=algorithm, timeout=REPLY_TIMEOUT_S
    ) as rov:
        check_sensors(rov.sensors())
    # Speaking crc8 to it, every checksummed query is dropped: connect says so.
    with pytest.raises(ConnectionError, match="not in checksum mode with crc8"):
        rovlink.connect(url, keepalive=None, checksum=True, timeout=0.1, retries=1)


def test_a_mode_left_over_from_an_earlier_session_is_reset_on_connect() -> None:
    port = open_port(seed=1)
    with port.lock:  # an earlier host left the controller in checksum mode
        port.controller.receive(b"#crcon!")
    options = ClientOptions(keepalive_s=None, timeout_s=REPLY_TIMEOUT_S)
    with Client(PortLink(port, "sim"), options) as rov:
        # The client sent #crcoff! on connect, so plain queries are answered.
        assert rov.depth_cm() >= 0
        assert not _state_of(rov)().checksum_enabled


def test_a_stop_lost_on_the_line_is_carried_again_by_the_keep_alives() -> None:
    # Before, a #stop! lost on a noisy line left the robot driving: nothing answers a #stop!,
    # and the keep-alive fed the controller's link-loss failsafe (P17). In simulated time, as
    # in the test above.
    port = SimulatedPort(SimConfig(controller=ControllerConfig(watchdog_s=2.0)), seed=4)

    def simulated_clock() -> float:
        with port.lock:
            return port.robot.time_s

    write = port.write
    lost: list[bytes] = []

    def losing_the_first_stop(data: bytes) -> int:
        if data == b"#stop!" and not lost:
            lost.append(data)
            return len(data)
        return write(data)

    port.write = losing_the_first_stop  # type: ignore[method-assign]
    options = ClientOptions(timeout_s=REPLY_TIMEOUT_S, keepalive_s=0.1)
    with Client(PortLink(port, "sim"), options, clock=simulated_clock) as rov:
        state = _state_of(rov)
        rov.start()
        rov.move(0, 30)
        rov.stop()
        assert lost
        assert (state().locked, state().power_percent) == (False, 30)  # driving on
        replies_before = rov.counters.replies
        for step in range(1, 4):  # 0.45 simulated seconds: well within the failsafe's 2 s
            port.advance(0.15)

            def answered(count: int = replies_before + step) -> bool:
                return rov.counters.replies >= count

            assert wait_until(answered)
        assert (state().locked, state().power_percent) == (True, 0)


def test_the_leak_latch_through_the_driver() -> None:
    url = "sim://?leak_at=0.05&seed=3"
    with rovlink.connect(url, keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        assert wait_until(rov.leak_detected)
        assert rov.sensors().leak_detected
        rov.reset_leak()
        assert rov.leak_detected() is False


@pytest.mark.parametrize("keepalive_s", [0.1, None])
def test_keepalive_holds_off_the_link_loss_failsafe(keepalive_s: float | None) -> None:
    # Simulated time moves only when the test advances it, and the client's clock reads it, so
    # the keep-alive interval, the watchdog and the idle time between frames are all counted
    # in simulated seconds: the outcome does not depend on how busy the machine is.
    port = SimulatedPort(SimConfig(controller=ControllerConfig(watchdog_s=0.3)), seed=4)

    def simulated_clock() -> float:
        with port.lock:  # never in the middle of a step: the client sees time between steps
            return port.robot.time_s

    options = ClientOptions(timeout_s=REPLY_TIMEOUT_S, keepalive_s=keepalive_s)
    with Client(PortLink(port, "sim"), options, clock=simulated_clock) as rov:
        state = _state_of(rov)
        rov.start()
        rov.move(0, 30)
        for step in range(1, 11):  # 1.5 simulated seconds: five times the watchdog
            port.advance(0.15)  # longer than the keep-alive interval, shorter than the watchdog
            if keepalive_s:
                # The idle link's keep-alive is sent, and answered, before time moves on.
                def answered(count: int = step) -> bool:
                    return rov.counters.replies >= count

                assert wait_until(answered)
        if keepalive_s:
            assert (state().locked, state().power_percent) == (False, 30)
            assert rov.counters.keepalives == 10
        else:  # the control case: without keep-alives the failsafe stops the robot
            assert (state().locked, state().power_percent) == (True, 0)


async def test_every_method_of_the_async_client() -> None:
    async with rovlink.aio.connect("sim://?seed=5", keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        state = _state_of(rov)
        await rov.set_debug(True)
        await rov.set_max_pwm(180)
        await rov.set_depth_pid(p=9)
        await rov.start()
        await rov.set_direct_mode(True)
        await rov.set_vertical_thrust(60)
        assert state().vertical_thrust_percent == 60
        await rov.set_direct_mode(False)
        await rov.hold_depth(80)
        await rov.move(90, 10)
        await rov.claw_open()
        await rov.claw_close()
        await rov.set_depth_zero(25)
        await rov.set_depth_scale(1100)
        await rov.reset_leak()
        current = state()
        assert (current.max_pwm, current.gains[0], current.target_depth_cm) == (180, 9, 80)
        assert (current.direction_deg, current.power_percent) == (90, 10)
        assert (current.depth_zero_raw, current.depth_k) == (25, 1100)
        results = await asyncio.gather(
            rov.depth_cm(),
            rov.pressure_raw(),
            rov.leak_detected(),
            rov.roll_deg(),
            rov.pitch_deg(),
            rov.heading_deg(),
            rov.sensors(),
        )
        assert results[2] is False
        check_sensors(results[6])  # type: ignore[arg-type]
        assert await rov.send_raw("#q.l!") == (Response("q.l", (0,)),)
        await rov.set_checksum(True)
        assert state().checksum_enabled
        readings = await asyncio.gather(*(rov.sensors() for _ in range(100)))
        for reading in readings:
            check_sensors(reading)
        await rov.stop()
        assert state().locked
        assert rov.counters.retries == 0


async def test_async_telemetry_from_the_simulator() -> None:
    async with rovlink.aio.connect("sim://?seed=6", keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        count = 0
        async for reading in rov.telemetry(None):
            check_sensors(reading)
            count += 1
            if count == 200:
                break
    # (Pipelined: the queries still in flight when the loop ended may be answered before the
    # client closes.)
    assert 200 <= rov.counters.replies <= 200 + DEFAULT_MAX_IN_FLIGHT


def test_sim_client_type() -> None:
    with rovlink.connect("sim://", keepalive=None) as rov:
        assert isinstance(rov, Client)
        assert rov.description == "simulated controller"
