"""MAVProxy, run headless as a real ground station, flies the bridge: parameters, arming, modes."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.bridges.mavlink.rig import BridgeRig, running_bridge, wait_for

pytestmark = pytest.mark.integration

MAVPROXY = Path(sys.executable).parent / "mavproxy.py"


class MavProxy:
    """``mavproxy.py`` with the modules a ground station needs, typed at over a pipe."""

    def __init__(
        self, master: str, workdir: Path, modules: str = "cmdlong,mode,arm,param,link,rc"
    ) -> None:
        self.process = subprocess.Popen(
            [
                sys.executable,
                str(MAVPROXY),
                f"--master={master}",
                "--no-state",
                f"--default-modules={modules}",
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=workdir,
        )
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines.append(line.rstrip())

    def wait_output(self, text: str, since: int = 0) -> str:
        wait_for(lambda: any(text in line for line in self.lines[since:]), timeout_s=20.0)
        return next(line for line in self.lines[since:] if text in line)

    def type(self, command: str) -> int:
        """Type a command; the output line index from which its answer appears."""
        mark = len(self.lines)
        assert self.process.stdin is not None
        self.process.stdin.write(command + "\n")
        self.process.stdin.flush()
        return mark

    def close(self) -> None:
        assert self.process.stdin is not None
        assert self.process.stdout is not None
        with contextlib.suppress(BrokenPipeError):
            self.process.stdin.close()  # (it ends on its input's end; SIGTERM alone is slow)
        if self.process.poll() is None:
            self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        # Its output is read to the end by the reader thread alone: communicate() read the
        # same pipe and closed it under the reader thread, which then failed.
        self._reader.join(timeout=10)
        if not self._reader.is_alive():
            self.process.stdout.close()


@pytest.fixture
def mavproxy_rig(tmp_path: Path) -> Iterator[tuple[BridgeRig, MavProxy]]:
    if not MAVPROXY.exists():
        pytest.skip("needs MAVProxy: pip install --no-deps MAVProxy")
    with running_bridge() as rig:
        proxy = MavProxy(rig.gcs_address, tmp_path)
        try:
            proxy.wait_output("online system 1")
            yield rig, proxy
        finally:
            proxy.close()


@pytest.mark.realtime
def test_mavproxy_with_ftp_and_fence_gets_the_parameters_at_once_and_no_breach(
    tmp_path: Path,
) -> None:
    # MAVProxy asks for the parameters by FTP first: unanswered, it retried for ten seconds
    # before it fell back to PARAM_REQUEST_LIST; its fence module said "fence breach".
    if not MAVPROXY.exists():
        pytest.skip("needs MAVProxy: pip install --no-deps MAVProxy")
    with running_bridge() as rig:
        proxy = MavProxy(rig.gcs_address, tmp_path, modules="ftp,param,fence,link")
        try:
            proxy.wait_output("online system 1")
            online_s = time.monotonic()
            proxy.wait_output("Received 39 parameters")
            assert time.monotonic() - online_s < 5.0
            mark = proxy.type("status SYS_STATUS")  # a SYS_STATUS seen: the fence judged
            proxy.wait_output("onboard_control_sensors_health", since=mark)
        finally:
            proxy.close()
    assert not [line for line in proxy.lines if "fence breach" in line or "FTP" in line]
    assert rig.bridge.parameters.value("RL_DEPTH_P") == 40


def test_mavproxy_lists_and_sets_parameters(mavproxy_rig: tuple[BridgeRig, MavProxy]) -> None:
    rig, proxy = mavproxy_rig
    proxy.wait_output("Received 39 parameters")
    line = proxy.wait_output("RL_DEPTH_P", proxy.type("param show RL_DEPTH_P"))
    assert line.split()[-1] == "40.0"
    mark = len(rig.frames())
    proxy.type("param set RL_DEPTH_I 12")
    rig.wait_frame("#mvpdi.12!", since=mark)
    wait_for(lambda: rig.bridge.parameters.value("RL_DEPTH_I") == 12)


def test_mavproxy_arms_switches_modes_and_disarms(mavproxy_rig: tuple[BridgeRig, MavProxy]) -> None:
    rig, proxy = mavproxy_rig
    mark = len(rig.frames())
    proxy.wait_output("COMPONENT_ARM_DISARM: ACCEPTED", proxy.type("arm throttle"))
    rig.wait_frame("#start!", since=mark)
    proxy.wait_output("DO_SET_MODE: ACCEPTED", proxy.type("mode ALT_HOLD"))
    rig.wait_frame("#mvdirect.0!", since=mark)
    proxy.wait_output("Mode ALT_HOLD")
    proxy.wait_output("DO_SET_MODE: DENIED", proxy.type("mode STABILIZE"))
    proxy.wait_output("COMPONENT_ARM_DISARM: ACCEPTED", proxy.type("disarm"))
    rig.wait_frame("#stop!", since=mark)


def test_mavproxy_going_away_while_armed_stops_the_robot(
    mavproxy_rig: tuple[BridgeRig, MavProxy],
) -> None:
    rig, proxy = mavproxy_rig
    proxy.wait_output("COMPONENT_ARM_DISARM: ACCEPTED", proxy.type("arm throttle"))
    mark = len(rig.frames())
    # Taken before the close: MAVProxy stops beating as it begins to end, and the close returns
    # once it has ended, up to a second later on a loaded machine (1 of 6 runs failed when this
    # was taken after it).
    closing_s = time.monotonic()
    proxy.close()  # the ground station dies: its heartbeats stop
    rig.wait_frame("#stop!", since=mark)
    assert time.monotonic() - closing_s >= 2.0  # the failsafe's 3 s, less the last beat's age


def test_mavproxy_flies_with_rc_overrides(mavproxy_rig: tuple[BridgeRig, MavProxy]) -> None:
    rig, proxy = mavproxy_rig
    mark = len(rig.frames())
    proxy.type("rc 3 1600")  # disarmed: nothing moves (P7)
    proxy.wait_output("COMPONENT_ARM_DISARM: ACCEPTED", proxy.type("arm throttle"))
    # MAVProxy repeats the override: once armed it is held at neutral, and said so.
    proxy.wait_output("RC 3 held: return to neutral")
    armed = len(rig.frames())
    proxy.type("rc 5 1400")  # forward channel, neutral at arming: astern at a quarter
    rig.wait_frame("#th.180.25!", since=mark)
    assert "#mvs.+25!" not in rig.frames_since(mark)  # channel 3 still held
    proxy.type("rc 3 1500")  # back to neutral ...
    proxy.type("rc 3 1600")  # ... then a fresh input drives
    rig.wait_frame("#mvs.+25!", since=armed)
    proxy.type("rc 3 0")  # released: neutral
    rig.wait_frame("#mvs.+0!", since=mark)
    proxy.type("rc clear")
    rig.wait_frame("#th.180.0!", since=mark)
    assert "#stop!" not in rig.frames_since(mark)
