"""The text of the monitor's panels, as rich ``Text``; the textual widgets only display it."""

from __future__ import annotations

from rich.text import Text

from rovlink.client import LinkCounters
from rovlink.monitor.compass import attitude_bar, heading_tape
from rovlink.monitor.readings import Readings
from rovlink.piloting import CommandedState, LinkHealth, LockState
from rovlink.protocol import Command

__all__ = [
    "STALE_AFTER_POLLS",
    "attitude_text",
    "commanded_text",
    "depth_text",
    "leak_text",
    "link_text",
]

#: A reading older than this many polling periods is shown as stale.
STALE_AFTER_POLLS = 3

_HEALTH_STYLES = {
    "ok": "bold green",
    "waiting": "yellow",
    "failing": "bold yellow",
    "no reply": "bold white on red",
}


def _row(text: Text, label: str, value: str | Text, style: str = "") -> None:
    text.append(f"{label:<11}", style="dim")
    if isinstance(value, Text):
        text.append_text(value)
    else:
        text.append(value, style=style)
    text.append("\n")


def _stale(readings: Readings, now_s: float, period_s: float) -> bool:
    age_s = readings.age_s(now_s)
    return age_s is not None and age_s > STALE_AFTER_POLLS * period_s


def depth_text(
    readings: Readings, commanded: CommandedState, *, now_s: float, period_s: float
) -> Text:
    """Target (as last sent) and raw pressure under the big depth figure."""
    text = Text()
    reading = readings.latest
    if commanded.target_depth_cm is not None:
        text.append(f"target {commanded.target_depth_cm} cm, as last sent\n")
    elif commanded.holding_entry_depth:
        text.append("target: depth on entry, as last sent\n")
    else:
        text.append("no target sent\n", style="dim")
    text.append("raw pressure ")
    text.append("—" if reading is None else f"{reading.pressure_raw}", style="bold")
    text.append("\n")
    if _stale(readings, now_s, period_s):
        text.append(f"stale: last reading {readings.age_s(now_s):.1f} s ago", style="bold yellow")
    text.rstrip()
    return text


def attitude_text(readings: Readings, width: int) -> Text:
    """Roll and pitch with their bars, heading with a compass tape."""
    text = Text()
    reading = readings.latest
    if reading is None:
        text.append("waiting for the first reading…", style="dim")
        return text
    bar_width = max(min(width - 20, 31), 9)
    _row(
        text,
        "roll",
        Text(f"{reading.roll_deg:+4d}°  ").append(
            attitude_bar(reading.roll_deg, bar_width), style="cyan"
        ),
    )
    _row(
        text,
        "pitch",
        Text(f"{reading.pitch_deg:+4d}°  ").append(
            attitude_bar(reading.pitch_deg, bar_width), style="cyan"
        ),
    )
    _row(text, "heading", f"{reading.heading_deg:4d}°", "bold")
    for line in heading_tape(reading.heading_deg, max(width, 9)):
        text.append(line + "\n", style="cyan")
    text.rstrip()
    return text


def leak_text(readings: Readings) -> Text:
    """The leak alarm, or the all-clear (or nothing known yet)."""
    if readings.latest is None:
        return Text("leak: no reading yet", style="dim")
    if readings.leak:
        return Text(
            "██ LEAK ██  the leak sensor fired (latched in the controller, q.l = 1)"
            "  ·  r resets the latch",
            style="bold white on red",
        )
    return Text("no leak (q.l = 0)", style="green")


def _drop_reason(commanded: CommandedState, command: Command) -> str:
    """Why the controller drops a command, in a few words (the notification says it all);
    a dropped command changes nothing, so the state now is the state it met."""
    if command.spec.motion and commanded.lock is LockState.LOCKED:
        return "locked"
    return f"{commanded.vertical_mode} mode"


def commanded_text(commanded: CommandedState) -> Text:
    """Lock, vertical mode and set-points, as last sent by this monitor (the panel says so)."""
    text = Text()
    lock_style = {LockState.LOCKED: "green", LockState.UNLOCKED: "bold yellow"}.get(
        commanded.lock, "dim"
    )
    _row(
        text,
        "motors",
        commanded.lock_text() if commanded.lock is not LockState.UNKNOWN else "unknown: none sent",
        lock_style,
    )
    _row(
        text,
        "vertical",
        commanded.short_mode_text()
        if commanded.vertical_mode is not None
        else "unknown: none sent",
    )
    _row(text, "horizontal", f"{commanded.direction_deg}° at {commanded.power_percent} %")
    last = commanded.last_command
    if last is None:
        _row(text, "last sent", "—", "dim")
    elif commanded.last_dropped_because is not None:
        _row(text, "last sent", f"{last}  (dropped: {_drop_reason(commanded, last)})", "yellow")
    else:
        _row(text, "last sent", str(last), "dim")
    text.rstrip()
    return text


def link_text(
    description: str,
    health: LinkHealth,
    counters: LinkCounters,
    readings: Readings,
    *,
    now_s: float,
    rate_hz: float,
) -> Text:
    """Link health: status, reply times, silence, timeouts, retries, checksum errors."""
    text = Text()
    status = health.status
    _row(
        text,
        "link",
        Text(f"{description} · polling {rate_hz:g} Hz · ").append(
            f" {status} ", style=_HEALTH_STYLES.get(status, "")
        ),
    )
    if health.last_reply_s is not None and health.average_reply_s is not None:
        _row(
            text,
            "reply time",
            f"{health.last_reply_s * 1000:.1f} ms (average {health.average_reply_s * 1000:.1f} ms)",
        )
    else:
        _row(text, "reply time", "—")
    age_s = readings.age_s(now_s)
    silence = "no reading yet" if age_s is None else f"last reading {age_s:.1f} s ago"
    silent_style = "bold red" if health.consecutive_failures else ""
    _row(text, "silence", silence, silent_style)
    failures = Text(
        f"timeouts {counters.timeouts} · retries {counters.retries} · "
        f"checksum errors {counters.checksum_errors} · "
    )
    failures.append(f"failed polls {health.failures}", style="bold red" if health.failures else "")
    _row(text, "errors", failures)
    text.rstrip()
    return text
