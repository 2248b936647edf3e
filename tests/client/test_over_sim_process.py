"""Both clients against ``rovlink sim`` in another process, over a real PTY and over TCP."""

from __future__ import annotations

import asyncio

import pytest

import rovlink
import rovlink.aio
from rovlink.client import ConnectionLostError
from tests.client.conftest import REPLY_TIMEOUT_S, wait_until
from tests.client.sim_process import running_sim
from tests.client.sim_scenario import DebugLines, check_sensors, run_every_method

pytestmark = pytest.mark.integration


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_every_method_over_a_real_transport(transport: str) -> None:
    with running_sim("--pty", "--tcp", "0", "--seed", "1") as sim:
        url = sim.pty_path if transport == "pty" else sim.tcp_url
        assert url is not None
        debug = DebugLines()
        with rovlink.connect(url, keepalive=None, on_stray=debug, timeout=REPLY_TIMEOUT_S) as rov:
            run_every_method(rov, debug)


def test_checksum_mode_from_the_start_over_a_paced_pty() -> None:
    with running_sim("--pty", "--baud", "115200", "--seed", "2") as sim:
        assert sim.pty_path is not None
        with rovlink.connect(
            sim.pty_path, checksum=True, baudrate=115200, timeout=REPLY_TIMEOUT_S
        ) as rov:
            for _ in range(20):
                check_sensors(rov.sensors())
            assert rov.counters.checksum_errors == 0


async def test_async_client_with_many_queries_in_flight_over_a_paced_pty() -> None:
    with running_sim("--pty", "--baud", "115200", "--seed", "3") as sim:
        assert sim.pty_path is not None
        async with rovlink.aio.connect(sim.pty_path, timeout=REPLY_TIMEOUT_S) as rov:
            readings = await asyncio.gather(*(rov.sensors() for _ in range(100)))
            for reading in readings:
                check_sensors(reading)
            headings = await asyncio.gather(*(rov.heading_deg() for _ in range(50)))
            assert all(0 <= heading <= 360 for heading in headings)
            assert rov.counters.retries == 0


async def test_async_client_over_tcp() -> None:
    with running_sim("--tcp", "0") as sim:
        assert sim.tcp_url is not None
        async with rovlink.aio.connect(sim.tcp_url, timeout=REPLY_TIMEOUT_S) as rov:
            await rov.set_checksum(True)
            results = await asyncio.gather(rov.depth_cm(), rov.leak_detected(), rov.sensors())
            assert results[1] is False
            check_sensors(results[2])


@pytest.mark.parametrize("transport", ["pty", "tcp"])
def test_the_simulator_going_away_is_a_lost_connection(transport: str) -> None:
    with running_sim("--pty", "--tcp", "0") as sim:
        url = sim.pty_path if transport == "pty" else sim.tcp_url
        assert url is not None
        rov = rovlink.connect(url, keepalive=None, timeout=REPLY_TIMEOUT_S)
        assert rov.depth_cm() >= 0
        sim.process.terminate()
        sim.process.wait(10)
        assert wait_until(lambda: rov.closed, timeout_s=5.0)
        with pytest.raises(ConnectionLostError):
            rov.depth_cm()
        rov.close()
