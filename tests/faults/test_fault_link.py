"""``fault://`` under the driver and ``rovlink fault`` as a proxy, with real sockets."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

import rovlink
from rovlink.cli import main
from rovlink.client import ClientOptions, ConnectError, ConnectionLostError
from rovlink.client.links import PortLink
from rovlink.faults import FaultPort, FaultSettings
from rovlink.sim.port import open_port
from tests.rovlink_process import running_rovlink


def test_driver_opens_fault_urls_and_checksums_keep_replies_right() -> None:
    url = "fault://?inner=sim%3A%2F%2F%3Fseed%3D1&ber=1e-3&delay_ms=2&jitter_ms=1&seed=4"
    with rovlink.connect(url, checksum=True, timeout=0.2, retries=6) as rov:
        depths = [rov.depth_cm() for _ in range(100)]
        counters = rov.counters
    assert all(0 <= depth <= 9999 for depth in depths)
    assert counters.replies >= 100


def test_bad_fault_url_is_a_clear_error() -> None:
    with pytest.raises(ValueError, match="inner URL"):
        rovlink.connect("fault://?inner=sim://?seed=x")
    with pytest.raises(ConnectError, match=r"inner link.*nonexistent-rovlink-port"):
        rovlink.connect("fault://?inner=/dev/nonexistent-rovlink-port")
    # A mistyped scheme is refused before anything is opened (it was a ConnectError).
    with pytest.raises(ValueError, match=r"inner URL: 'nope://x': unknown URL scheme nope://"):
        rovlink.connect("fault://?inner=nope://x")
    with pytest.raises(ValueError, match="inner=URL is required"):
        rovlink.connect("fault://?ber=0.1")


def test_delays_keep_order_and_hold_bytes_back() -> None:
    sim = open_port(seed=1, timeout=0.05)
    port = FaultPort(PortLink(sim, "sim"), FaultSettings(delay_ms=30, jitter_ms=10, seed=2))
    port.timeout = 1.0
    try:
        started = time.monotonic()
        for _ in range(20):
            port.write(b"#qd!")
        received = b""
        while received.count(b"!") < 20:
            received += port.read(4096)
        assert time.monotonic() - started >= 0.02  # nothing came before the shortest delay
        assert received.count(b"$qd.") == 20
        assert port.counters["to_controller"].chunks_delayed == 20
    finally:
        port.close()


def test_a_dead_inner_link_is_reported() -> None:
    sim = open_port(seed=1, timeout=0.05)
    port = FaultPort(PortLink(sim, "sim"), FaultSettings(seed=1))
    sim.close()
    port.timeout = 0.5
    deadline = time.monotonic() + 5
    while port.is_open and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not port.is_open
    with pytest.raises(ConnectionError, match="closed"):
        port.write(b"#qd!")
    port.close()


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def _wait_for_line(process: subprocess.Popen[str], text: str) -> str:
    assert process.stdout is not None
    line = process.stdout.readline()
    assert text in line, line
    return line


@pytest.mark.integration
def test_proxy_serves_any_client_and_stops_the_robot_when_it_goes() -> None:
    sim_port = _free_port()
    proxy_port = _free_port()
    sim = subprocess.Popen(
        [sys.executable, "-m", "rovlink", "sim", "--tcp", str(sim_port), "--watchdog", "0"],
        stdout=subprocess.PIPE,
        text=True,
    )
    proxy = None
    try:
        _wait_for_line(sim, "ready")
        proxy = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "rovlink",
                "fault",
                "--listen",
                f"socket://127.0.0.1:{proxy_port}",
                "--to",
                f"socket://127.0.0.1:{sim_port}",
                "--ber",
                "1e-4",
                "--seed",
                "3",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        _wait_for_line(proxy, "ready")
        options = ClientOptions(checksum=True, timeout_s=0.3, retries=5, motion_timeout_s=None)
        url = f"socket://127.0.0.1:{proxy_port}"
        rov = rovlink.connect(url, options=options)
        rov.start()
        rov.set_direct_mode(True)
        rov.set_vertical_thrust(-40)
        assert rov.depth_cm() >= 0
        rov.close()  # the client goes without a #stop!: the proxy must send one
        # Connect again through the proxy and see the motors locked: the thrust is refused.
        # Until the proxy has seen the first client go and sent #stop!, it says busy.
        deadline = time.monotonic() + 10
        while True:
            try:
                rov = rovlink.connect(url, options=options)
                break
            except (ConnectError, ConnectionLostError):
                assert time.monotonic() < deadline
                time.sleep(0.05)
        # The depth settles (a robot still driven at -40 % dives some 10 cm every half
        # second): waited for, as a busy machine may read the first depth while it still sinks.
        previous = rov.depth_cm()
        deadline = time.monotonic() + 10
        while True:
            time.sleep(0.5)  # (the interval between two readings, not a wait for an event)
            depth = rov.depth_cm()
            if depth <= previous + 1:
                break
            assert time.monotonic() < deadline, "the robot kept diving after its client left"
            previous = depth
        rov.close()
    finally:
        if proxy is not None:
            proxy.terminate()
            _, err = proxy.communicate(timeout=10)
            assert "to controller:" in err
            assert "bits flipped" in err
        sim.terminate()
        sim.wait(timeout=10)


def test_fault_refuses_a_non_loopback_listen_address_without_allow_remote(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Before, it listened on 0.0.0.0 without a word, where rovlink controller refuses it.
    argv = ["fault", "--listen", "socket://0.0.0.0:5761", "--to", "sim://"]
    assert main(argv) == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert "0.0.0.0 is not a loopback address" in error
    assert "--allow-remote" in error


@pytest.mark.integration
def test_the_ready_line_gives_an_ipv6_listener_as_a_url_that_opens() -> None:
    # Before, it printed socket://::1:PORT, which no client parses; the ready line is the URL
    # that users copy into their program.
    with socket.socket(socket.AF_INET6) as probe:
        probe.bind(("::1", 0))
        port = int(probe.getsockname()[1])
    with running_rovlink(
        "fault", "--listen", f"socket://[::1]:{port}", "--to", "sim://", ready_timeout_s=10
    ) as (_, ready):
        url = ready.split()[3]
        assert url == f"socket://[::1]:{port}", ready
        with rovlink.connect(url, timeout=0.5) as rov:
            assert rov.depth_cm() >= 0


@pytest.mark.integration
def test_listen_on_port_0_serves_a_free_port_and_the_ready_line_names_it() -> None:
    # Before, port 0 was refused ("a port in 1–65535"), where rovlink sim --tcp 0 and
    # rovlink record --tap take it: a CI job had to pick a port and hope it stayed free.
    with running_rovlink(
        "fault", "--listen", "socket://127.0.0.1:0", "--to", "sim://", ready_timeout_s=10
    ) as (_, ready):
        url = ready.split()[3]
        port = int(url.rpartition(":")[2])
        assert url == f"socket://127.0.0.1:{port}", ready
        assert port != 0, ready
        with rovlink.connect(url, timeout=0.5) as rov:
            assert rov.depth_cm() >= 0


@pytest.mark.integration
def test_the_proxy_says_on_exit_how_many_clients_it_served_and_refused(tmp_path: Path) -> None:
    # Before, the counts were kept but never said: a program told "busy" and disconnected
    # showed in no report, only as a client that never got an answer.
    port = _free_port()
    url = f"socket://127.0.0.1:{port}"
    with (tmp_path / "stderr").open("w+") as stderr:
        with (
            running_rovlink(
                "fault", "--listen", url, "--to", "sim://", ready_timeout_s=10, stderr=stderr
            ),
            rovlink.connect(url, timeout=0.5) as rov,
        ):
            assert rov.depth_cm() >= 0
            with socket.create_connection(("127.0.0.1", port)) as second:
                second.settimeout(5)
                assert second.recv(100).startswith(b"busy:")
        stderr.seek(0)
        said = stderr.read()
    assert "clients: 1 served, 1 refused (busy)" in said, said


@pytest.mark.parametrize(
    ("option", "too_high", "shown"),
    [
        ("--ber", "0.6", "0–0.5"),
        ("--drop", "1.1", "0–1"),
        ("--dup", "1.1", "0–1"),
        ("--delay-ms", "10001", "0–10000"),
    ],
)
def test_fault_help_gives_the_range_each_rate_and_delay_is_checked_against(
    capsys: pytest.CaptureFixture[str], option: str, too_high: str, shown: str
) -> None:
    # Before, --help gave the defaults alone: a user learnt the range from a refused value.
    listen = ("--listen", "socket://127.0.0.1:5761", "--to", "sim://")
    assert main(["fault", *listen, option, too_high]) == 2
    assert f"argument {option}" in capsys.readouterr().err
    assert main(["fault", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    described = text[text.index(f"{option} ", text.index("options:")) :]
    assert shown in described[: described.index("(default")], described[:200]


@pytest.mark.integration
def test_a_listener_other_computers_reach_is_said_loudly(tmp_path: Path) -> None:
    # As rovlink sim and rovlink controller say it. Before, --allow-remote served the robot,
    # unauthenticated, to every network with a ready line like any other.
    port = _free_port()
    listen = f"socket://0.0.0.0:{port}"
    with (tmp_path / "stderr").open("w+") as stderr:
        with running_rovlink(
            "fault", "--listen", listen, "--to", "sim://", "--allow-remote",
            ready_timeout_s=10, stderr=stderr,
        ) as (_, ready):  # fmt: skip
            assert ready.startswith(f"rovlink fault ready: {listen} (REMOTE, NO AUTHENTICATION) ")
        stderr.seek(0)
        said = stderr.read()
    assert f"listening on 0.0.0.0:{port} (every network interface)" in said, said
    assert "anyone connected can drive the robot" in said
