"""Every serving command, run as a user runs it and ended by a signal, says how it ended in one
line, with the status that goes with it: ``rovlink sim: interrupted`` and 130 after Ctrl-C, as
for every command; ``rovlink sim stopped`` and 0 after SIGTERM, how a service manager stops it.

Before, ``sim`` and ``controller`` said both "stopped" and "interrupted" on Ctrl-C, and ``web``,
``fault`` and ``record`` said nothing of a SIGTERM."""

from __future__ import annotations

import selectors
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.bridges.mavlink.rig import free_udp_port
from tests.bridges.mqtt.broker import Mosquitto, running_broker
from tests.rovlink_process import rovlink_command, rovlink_environment

pytestmark = pytest.mark.integration

_READY_TIMEOUT_S = 30.0  # (a loaded machine: generous, the ready line is expected)
_END_TIMEOUT_S = 20.0


def _ready(process: subprocess.Popen[str]) -> str:
    """Read both outputs until the ready line (``…; Ctrl-C stops``, on either): what was read."""
    assert process.stdout is not None
    assert process.stderr is not None
    read = ""
    deadline = time.monotonic() + _READY_TIMEOUT_S
    with selectors.DefaultSelector() as selector:
        selector.register(process.stdout, selectors.EVENT_READ)
        selector.register(process.stderr, selectors.EVENT_READ)
        while "Ctrl-C stops" not in read:
            left_s = deadline - time.monotonic()
            assert left_s > 0, f"no ready line: {read!r}"
            for key, _ in selector.select(left_s):
                line = key.fileobj.readline()  # type: ignore[union-attr]
                assert line, f"ended before its ready line: {read!r}"
                read += line
    return read


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    yield from running_broker(tmp_path)


def _arguments(name: str, tmp_path: Path, request: pytest.FixtureRequest) -> list[str]:
    if name == "sim":
        return ["sim", "--tcp", "127.0.0.1:0"]
    if name == "controller":
        return ["controller", "--board", "sim", "--tcp", "127.0.0.1:0"]
    if name == "fault":
        return ["fault", "--listen", "socket://127.0.0.1:0", "--to", "sim://"]
    if name == "web":
        return ["web", "--port", "0"]
    if name == "record":
        return ["record", "sim://", "-o", str(tmp_path / "dive.jsonl")]
    if name == "mavlink":
        return ["mavlink", "--out", f"udpout:127.0.0.1:{free_udp_port()}"]
    assert name == "mqtt"
    pytest.importorskip("aiomqtt", reason="needs aiomqtt: pip install 'rovlink[mqtt]'")
    mosquitto: Mosquitto = request.getfixturevalue("broker")
    return ["mqtt", "--broker", mosquitto.url, "--robot", "rov-1"]


@pytest.mark.parametrize(
    ("how", "status", "ending"),
    [(signal.SIGINT, 130, ": interrupted"), (signal.SIGTERM, 0, " stopped")],
    ids=["SIGINT", "SIGTERM"],
)
@pytest.mark.parametrize("name", ["sim", "controller", "fault", "web", "record", "mavlink", "mqtt"])
def test_a_serving_command_says_in_one_line_how_a_signal_ended_it(
    name: str,
    how: signal.Signals,
    status: int,
    ending: str,
    tmp_path: Path,
    request: pytest.FixtureRequest,
) -> None:
    process = subprocess.Popen(
        rovlink_command(*_arguments(name, tmp_path, request)),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=rovlink_environment(),
    )
    try:
        _ready(process)
        process.send_signal(how)
        _, stderr = process.communicate(timeout=_END_TIMEOUT_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    said = [line for line in stderr.splitlines() if "stopped" in line or "interrupted" in line]
    assert said == [f"rovlink {name}{ending}"], stderr
    assert process.returncode == status, stderr
    assert "Traceback" not in stderr
