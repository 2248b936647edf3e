"""Every method of the driver against a simulated controller, checked through its debug text.

The same scenario runs in process (``sim://``), over a PTY and over TCP: the controller's debug
output (P5) says what each set command did, so it works wherever the controller runs.
"""

from __future__ import annotations

import threading

from rovlink.client import Client, Sensors
from rovlink.protocol import Event, Text
from tests.client.conftest import wait_until


class DebugLines:
    """Collects the controller's debug text from ``on_stray`` (called in another thread)."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._lock = threading.Lock()

    def __call__(self, event: Event) -> None:
        if isinstance(event, Text):
            with self._lock:
                self.lines.append(event.text)

    def count(self, fragment: str) -> int:
        with self._lock:
            return sum(fragment in line for line in self.lines)

    def expect(self, fragment: str, times: int = 1) -> None:
        assert wait_until(lambda: self.count(fragment) >= times), (
            f"no debug line with {fragment!r}; got {self.lines}"
        )


def check_sensors(reading: Sensors) -> None:
    """Every reading within its protocol range."""
    assert 0 <= reading.depth_cm <= 9999
    assert 0 <= reading.pressure_raw <= 1024
    assert isinstance(reading.leak_detected, bool)
    assert -90 <= reading.roll_deg <= 90
    assert -90 <= reading.pitch_deg <= 90
    assert 0 <= reading.heading_deg <= 360


def run_every_method(rov: Client, debug: DebugLines) -> None:
    """Call every method; check each set command's effect in the controller's debug text."""
    rov.set_debug(True)
    debug.expect("debug output on")
    rov.set_max_pwm(200)
    debug.expect("max PWM 200")
    rov.set_depth_pid(p=11, i=2, d=3)
    debug.expect("depth PID", times=3)
    rov.start()
    debug.expect("motors unlocked")
    rov.set_direct_mode(True)
    debug.expect("vertical mode direct")
    rov.set_vertical_thrust(-40)
    debug.expect("vertical thrust -40 %")
    rov.set_direct_mode(False)
    debug.expect("vertical mode depth")
    rov.hold_depth(150)
    debug.expect("target depth 150 cm")
    rov.move(270, 25)
    debug.expect("horizontal 270 deg at 25 %")
    rov.claw_open()
    debug.expect("claw opening")
    rov.claw_close()
    debug.expect("claw closing")
    rov.set_depth_zero(30)
    debug.expect("depth zero 30")
    rov.set_depth_scale(900)
    debug.expect("depth coefficient k 900")
    rov.reset_leak()
    debug.expect("leak latch reset")
    check_sensors(rov.sensors())
    assert 0 <= rov.depth_cm() <= 9999
    assert 0 <= rov.pressure_raw() <= 1024
    assert rov.leak_detected() is False
    assert -90 <= rov.roll_deg() <= 90
    assert -90 <= rov.pitch_deg() <= 90
    assert 0 <= rov.heading_deg() <= 360
    rov.set_checksum(True)
    debug.expect("checksum mode on")
    check_sensors(rov.sensors())
    rov.move(90, 10)
    debug.expect("horizontal 90 deg at 10 %")
    rov.set_checksum(False)
    debug.expect("checksum mode off")
    (reply,) = rov.send_raw("#qhe!")
    assert reply.name == "qhe"
    rov.stop()
    debug.expect("motors stopped and locked")
    counters = rov.counters
    assert (counters.timeouts, counters.retries, counters.bad_frames) == (0, 0, 0)
