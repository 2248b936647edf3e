"""The panels' text: honest about what is known, loud about a leak and a silent link."""

from __future__ import annotations

from rovlink.client import LinkCounters, Sensors
from rovlink.monitor.panels import (
    attitude_text,
    commanded_text,
    controller_message_text,
    depth_text,
    leak_text,
    link_text,
    stale_text,
)
from rovlink.monitor.readings import Readings
from rovlink.piloting import CommandedState, LinkHealth, LockState
from rovlink.protocol import Command, VerticalMode

READING = Sensors(
    depth_cm=57, pressure_raw=612, leak_detected=False, roll_deg=-3, pitch_deg=2, heading_deg=275
)


def _readings(*readings: tuple[Sensors, float]) -> Readings:
    result = Readings(window_s=30.0)
    for reading, at_s in readings:
        result.record(reading, at_s)
    return result


def test_depth_readout_says_as_last_sent() -> None:
    readings = _readings((READING, 10.0))
    commanded = CommandedState(vertical_mode=VerticalMode.DEPTH, target_depth_cm=60)
    text = depth_text(readings, commanded).plain
    assert "target 60 cm, as last sent" in text
    assert "raw pressure 612" in text
    assert "no target sent" in depth_text(readings, CommandedState()).plain


def test_a_reading_goes_stale_after_three_polling_periods() -> None:
    readings = _readings((READING, 10.0))
    assert stale_text(readings, now_s=10.6, period_s=0.2) is None
    assert stale_text(readings, now_s=11.0, period_s=0.2) == "stale: 1.0 s old"
    assert stale_text(Readings(), now_s=11.0, period_s=0.2) is None


def test_the_controllers_last_message_goes_stale_as_a_reading_does() -> None:
    # Regression: the controller's last message looked as current minutes later as when it came.
    fresh = controller_message_text("debug: hold", age_s=0.6, period_s=0.2)
    assert fresh.plain == "debug: hold"
    assert "dim" not in str(fresh.style)
    old = controller_message_text("debug: hold", age_s=125.0, period_s=0.2)
    assert old.plain == "debug: hold  (125.0 s ago)"
    assert "dim" in str(old.style)
    assert "yellow" not in str(old.style)


def test_stale_values_are_dimmed_and_a_stale_all_clear_is_no_all_clear() -> None:
    # Regression: only the depth box said a reading was old; roll, pitch, heading, the compass
    # and a green "no leak" went on looking live.
    readings = _readings((READING, 1.0))
    attitude = attitude_text(readings, 40, stale=True)
    assert "heading     275°" in attitude.plain
    assert not [span for span in attitude.spans if "cyan" in str(span.style)]
    assert "bold" not in str(attitude.spans)
    assert "dim" in str(attitude.style)
    leak = leak_text(readings, stale=True)
    assert "no leak" in leak.plain
    assert leak.plain.startswith("leak unknown")
    assert "green" not in str(leak.style)
    depth = depth_text(readings, CommandedState(), stale=True)
    assert "raw pressure 612" in depth.plain
    assert "bold" not in str(depth.spans)
    leaking = _readings((Sensors(57, 612, True, 0, 0, 0), 2.0))
    assert leak_text(leaking, stale=True).plain.startswith("██ LEAK ██")  # the latch holds


def test_leak_banner() -> None:
    assert leak_text(Readings()).plain == "leak: no reading yet"
    assert leak_text(_readings((READING, 1.0))).plain == "no leak (q.l = 0)"
    leaking = _readings((Sensors(57, 612, True, 0, 0, 0), 2.0))
    banner = leak_text(leaking)
    assert banner.plain.startswith("██ LEAK ██")
    assert "r resets the latch" in banner.plain
    assert "red" in str(banner.style)


def test_leak_since_is_kept_until_a_clear_reading() -> None:
    readings = _readings((Sensors(0, 20, True, 0, 0, 0), 1.0), (Sensors(0, 20, True, 0, 0, 0), 2.0))
    assert readings.leak_since_s == 1.0
    readings.record(READING, 3.0)
    assert not readings.leak


def test_attitude() -> None:
    text = attitude_text(_readings((READING, 1.0)), width=40).plain
    assert "roll         -3°" in text
    assert "pitch        +2°" in text
    assert "heading     275°" in text
    assert "W" in text
    assert "▲" in text
    assert attitude_text(Readings(), 40).plain == "waiting for the first reading…"


def test_commanded_panel() -> None:
    state = CommandedState()
    text = commanded_text(state).plain
    assert text.count("unknown: none sent") == 2
    state.apply(Command("start"))
    state.apply(Command("th", (90, 30)))
    text = commanded_text(state).plain
    assert "unlocked (as last sent)" in text
    assert "90° at 30 %" in text
    assert "last sent  #th.90.30!" in text
    assert state.lock is LockState.UNLOCKED


def test_keys_pressed_while_locked_show_as_last_sent() -> None:
    # Regression: a motion command the controller drops (locked) was not shown as last sent.
    state = CommandedState()
    state.apply(Command("stop"))
    state.apply(Command("th", (90, 30)))
    text = commanded_text(state).plain
    assert "last sent  #th.90.30!  (dropped: locked)" in text
    assert "0° at 0 %" in text  # the set-point is the one the controller has
    state.apply(Command("start"))
    state.apply(Command("mvdirect", (1,)))
    state.apply(Command("mvd", (50,)))
    assert "last sent  #mvd.50!  (dropped: direct mode)" in commanded_text(state).plain
    state.apply(Command("mvs", (20,)))
    assert commanded_text(state).plain.endswith("last sent  #mvs.+20!")


def test_link_panel_healthy_and_silent() -> None:
    health = LinkHealth()
    health.record_reply(0.0031, now_s=5.0)
    readings = _readings((READING, 5.0))
    text = link_text("bench", health, LinkCounters(), readings, now_s=5.5, rate_hz=5).plain
    assert "bench · polling 5 Hz ·  ok" in text
    assert "3.1 ms" in text
    assert "last reading 0.5 s ago" in text
    for _ in range(3):
        health.record_failure("no reply", now_s=6.0)
    counters = LinkCounters(timeouts=9, retries=6, checksum_errors=2)
    text = link_text("bench", health, counters, readings, now_s=9.0, rate_hz=5).plain
    assert " no reply " in text
    # (Before, "3.1 ms" as if the link answered in that time now.)
    assert "reply time none now (last 3.1 ms, average 3.1 ms)" in text
    assert "last reading 4.0 s ago" in text
    reopening = link_text("bench", health, counters, readings, now_s=9, rate_hz=5, reopening=True)
    assert "none now (last 3.1 ms" in reopening.plain
    assert "timeouts 9 · retries 6 · checksum errors 2 · failed polls 3" in text
