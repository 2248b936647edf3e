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
    "controller_message_text",
    "depth_text",
    "leak_text",
    "link_text",
    "small_screen_text",
    "stale_text",
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


def stale_text(readings: Readings, *, now_s: float, period_s: float) -> str | None:
    """What marks every reading shown once the latest is older than ``STALE_AFTER_POLLS``
    polling periods; ``None`` while it is fresh (or before the first).

    >>> from rovlink.client import Sensors
    >>> readings = Readings()
    >>> readings.record(Sensors(120, 530, False, -1, 3, 275), at_s=5.0)
    >>> stale_text(readings, now_s=5.5, period_s=0.2) is None
    True
    >>> stale_text(readings, now_s=11.5, period_s=0.2)
    'stale: 6.5 s old'
    """
    age_s = readings.age_s(now_s)
    if age_s is None or age_s <= STALE_AFTER_POLLS * period_s:
        return None
    return f"stale: {age_s:.1f} s old"


def controller_message_text(message: str, *, age_s: float, period_s: float) -> Text:
    """The controller's last message (debug text, a dropped reply): as it came while it is
    fresh; dimmed, with its age, once it is older than ``STALE_AFTER_POLLS`` polling periods,
    as a reading is (else a message of minutes ago looks like one of now).

    >>> controller_message_text("debug: depth hold", age_s=0.4, period_s=0.2).plain
    'debug: depth hold'
    >>> controller_message_text("debug: depth hold", age_s=6.5, period_s=0.2).plain
    'debug: depth hold  (6.5 s ago)'
    """
    if age_s <= STALE_AFTER_POLLS * period_s:
        return Text(message, style="italic yellow")
    return Text(f"{message}  ({age_s:.1f} s ago)", style=_value_style(True))


def depth_text(readings: Readings, commanded: CommandedState, *, stale: bool = False) -> Text:
    """Target (as last sent) and raw pressure under the big depth figure; a ``stale`` reading
    is dimmed (the box says how old it is)."""
    text = Text()
    reading = readings.latest
    if commanded.target_depth_cm is not None:
        text.append(f"target {commanded.target_depth_cm} cm, as last sent\n")
    elif commanded.holding_entry_depth:
        text.append("target: depth on entry, as last sent\n")
    else:
        text.append("no target sent\n", style="dim")
    text.append("raw pressure ")
    text.append("—" if reading is None else f"{reading.pressure_raw}", style=_value_style(stale))
    return text


def _value_style(stale: bool, live: str = "bold") -> str:
    # A stale value is still shown (the last known), but never in the look of a live one.
    return "dim" if stale else live


def attitude_text(readings: Readings, width: int, *, stale: bool = False) -> Text:
    """Roll and pitch with their bars, heading with a compass tape; all dimmed when ``stale``
    (the panel says how old the reading is)."""
    text = Text(style=_value_style(stale, ""))
    reading = readings.latest
    if reading is None:
        text.append("waiting for the first reading…", style="dim")
        return text
    bar_style = _value_style(stale, "cyan")
    bar_width = max(min(width - 20, 31), 9)
    _row(
        text,
        "roll",
        Text(f"{reading.roll_deg:+4d}°  ").append(
            attitude_bar(reading.roll_deg, bar_width), style=bar_style
        ),
    )
    _row(
        text,
        "pitch",
        Text(f"{reading.pitch_deg:+4d}°  ").append(
            attitude_bar(reading.pitch_deg, bar_width), style=bar_style
        ),
    )
    _row(text, "heading", f"{reading.heading_deg:4d}°", _value_style(stale))
    for line in heading_tape(reading.heading_deg, max(width, 9)):
        text.append(line + "\n", style=bar_style)
    text.rstrip()
    return text


def leak_text(readings: Readings, *, stale: bool = False) -> Text:
    """The leak alarm, or the all-clear (or nothing known yet). A leak stays an alarm however
    old its reading (the latch holds until reset); a stale all-clear is no all-clear."""
    if readings.latest is None:
        return Text("leak: no reading yet", style="dim")
    if readings.leak:
        return Text(
            "██ LEAK ██  the leak sensor fired (latched in the controller, q.l = 1)"
            "  ·  r resets the latch",
            style="bold white on red",
        )
    if stale:
        return Text("leak unknown: the last reading said no leak (q.l = 0)", style="bold yellow")
    return Text("no leak (q.l = 0)", style="green")


def _drop_reason(commanded: CommandedState, command: Command) -> str:
    """Why the controller drops a command, in a few words (the notification says it all);
    a dropped command changes nothing, so the state now is the state it met."""
    if command.spec.motion and commanded.lock is LockState.LOCKED:
        return "locked"
    return f"{commanded.vertical_mode} mode"


#: The longest lock text the commanded box shows in full.
_LOCK_WIDTH = 34


def commanded_text(commanded: CommandedState) -> Text:
    """Lock, vertical mode and set-points, as last sent by this monitor (the panel says so), or
    the lock as the controller announced it since (``locked (stopped by another line)``)."""
    text = Text()
    lock_style = {LockState.LOCKED: "green", LockState.UNLOCKED: "bold yellow"}.get(
        commanded.latest_lock, "dim"
    )
    lock = commanded.lock_text()
    if commanded.heard_lock is not None:  # announced by the controller (debug output on)
        if len(lock) > _LOCK_WIDTH:  # (a failsafe's reason; a notice says it in full)
            lock = commanded.short_lock_text()
    elif commanded.lock is LockState.UNKNOWN:  # (in the box's width; a notice says it in full)
        lock = "unknown: none sent"
        if commanded.lock_unknown_after_reset:
            lock = "unknown: reset suspected"
        elif commanded.lock_unknown_after_reopening:
            lock = "unknown: link reopened"
    _row(text, "motors", lock, lock_style)
    mode = commanded.short_mode_text()
    if commanded.vertical_mode is None:
        mode = (
            "unknown: reset suspected"
            if commanded.mode_unknown_after_reset
            else "unknown: none sent"
        )
    _row(text, "vertical", mode)
    _row(text, "horizontal", f"{commanded.direction_deg}° at {commanded.power_percent} %")
    last = commanded.last_command
    if last is None:
        reopened = commanded.last_forgotten_on_reopening
        _row(text, "last sent", "— since the link was reopened" if reopened else "—", "dim")
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
    reopening: bool = False,
) -> Text:
    """Link health: status, reply times, silence, timeouts, retries, checksum errors.
    ``reopening``: the link was lost and is being reopened, which the status says instead."""
    text = Text()
    status = "lost, reopening it" if reopening else health.status
    style = "bold white on red" if reopening else _HEALTH_STYLES.get(status, "")
    _row(
        text,
        "link",
        Text(f"{description} · polling {rate_hz:g} Hz · ").append(f" {status} ", style=style),
    )
    if health.last_reply_s is not None and health.average_reply_s is not None:
        last_ms, average_ms = health.last_reply_s * 1000, health.average_reply_s * 1000
        if reopening or health.consecutive_failures:
            # (Shown as it was, the last answer's time read as the link's now.)
            _row(
                text,
                "reply time",
                f"none now (last {last_ms:.1f} ms, average {average_ms:.1f} ms)",
                "bold red",
            )
        else:
            _row(text, "reply time", f"{last_ms:.1f} ms (average {average_ms:.1f} ms)")
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


def small_screen_text(
    readings: Readings,
    commanded: CommandedState | None,
    link: str,
    *,
    stale: str | None,
    size: tuple[int, int],
    needed: tuple[int, int],
) -> Text:
    """The essentials one per line, the most urgent first, for a terminal of ``size`` (columns,
    rows) too small for the boxes (``needed``): the keys that stop and quit, a leak, the depth,
    the state as last sent, the link. Each line is cut to the width, never wrapped.

    >>> from rovlink.client import Sensors
    >>> readings = Readings()
    >>> readings.record(Sensors(120, 530, True, -1, 3, 275), at_s=5.0)
    >>> print(small_screen_text(readings, CommandedState(), "ok", stale=None, size=(20, 5),
    ...                         needed=(80, 24)).plain)
    space STOP · q quit
    LEAK (q.l = 1) · r resets the latch
    depth 120 cm
    motors lock not sent · 0° at 0 % (as last sent)
    link ok
    terminal 20×5: too small for the dashboard, which needs 80×24
    """
    text = Text(no_wrap=True, overflow="ellipsis")
    text.append("space STOP · q quit\n", style="bold")
    if readings.leak:
        text.append("LEAK (q.l = 1) · r resets the latch\n", style="bold white on red")
    reading = readings.latest
    depth = "depth —" if reading is None else f"depth {reading.depth_cm} cm"
    text.append(
        depth + (f" ({stale})" if stale else "") + "\n", style=_value_style(stale is not None)
    )
    if commanded is not None:
        text.append(
            f"motors {commanded.short_lock_text()} · {commanded.direction_deg}° at "
            f"{commanded.power_percent} % (as last sent)\n",
            style="bold yellow" if commanded.latest_lock is LockState.UNLOCKED else "",
        )
    text.append(f"link {link}\n", style=_HEALTH_STYLES.get(link, ""))
    columns, rows = size
    text.append(
        f"terminal {columns}×{rows}: too small for the dashboard, which needs "
        f"{needed[0]}×{needed[1]}",
        style="dim",
    )
    return text
