"""A dive on shared time axes: depth against set-point, thrust, attitude, heading, and the leak
and link events, drawn with matplotlib (the ``plot`` extra) from a recording.

Example::

    figure = plot_dive(read_entries("dive.mcap"), title="dive.mcap")
    figure.savefig("dive.png")
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from rovlink.recorder.entries import Entry, EventEntry, HeaderEntry, TelemetryEntry, utc_text

__all__ = ["FIGURE_SIZE_IN", "DiveSeries", "collect", "plot_dive", "plot_series"]

#: Events drawn as markers on the link panel, with their label and colour.
_LINK_MARKERS: dict[str, tuple[str, str]] = {
    "query_failed": ("query failed", "tab:red"),
    "bad_frame": ("bad frame", "tab:orange"),
    "late_reply": ("late reply", "tab:purple"),
    "reset_suspected": ("reset suspected", "black"),
    "link": ("link state", "tab:gray"),
    # (Both were "link state": which line was the loss and which the return, nobody could tell.)
    "link lost": ("link lost", "tab:pink"),
    "link reconnected": ("link reconnected", "tab:green"),
    "motion_expired": ("motion expired", "tab:brown"),
    # (A leak latched by the reply that ends a dive was drawn as nothing: its step starts at
    # the last row.)
    "leak": ("leak latch change", "tab:red"),
}


@dataclass
class DiveSeries:
    """The columns of a recording's telemetry, and its events, against time from its start."""

    time_s: list[float] = field(default_factory=list)
    columns: dict[str, list[float]] = field(default_factory=dict)
    events: list[tuple[float, str]] = field(default_factory=list)
    #: Who recorded it (``rovlink demo on sim://``), from its header; empty for a ``.csv``.
    recorded_by: str = ""
    #: The wall clock at time 0, ns since the Unix epoch.
    start_wall_ns: int | None = None

    def describe(self) -> str:
        """Who recorded the dive and when it started (UTC), for the figure's title.

        >>> DiveSeries(recorded_by="rovlink demo on sim://", start_wall_ns=0).describe()
        'rovlink demo on sim://, started 1970-01-01 00:00:00 UTC'
        """
        parts = [self.recorded_by] if self.recorded_by else []
        started = None if self.start_wall_ns is None else utc_text(self.start_wall_ns)
        if started is not None:
            parts.append(f"started {started}")
        return ", ".join(parts)


def collect(entries: Iterable[Entry]) -> DiveSeries:
    """The telemetry columns and events of ``entries`` (``nan`` where a value is not known),
    taken one entry at a time: an hour's recording is never held whole. The last row's values
    hold to the recording's end (its last entry of any channel)."""
    series = DiveSeries()
    first_s: float | None = None
    last_s = -math.inf  # (the recording's end: its last entry of any channel)
    # A table without events (a .csv has no header, and no leak event): the latch's changes are
    # read from its column, or a leak that aborted a dive showed as a step at its last row.
    events_recorded = False
    leak: int | None = None
    for entry in entries:
        if isinstance(entry, HeaderEntry):  # (written as the file starts: not its end)
            series.recorded_by = f"{entry.program} on {entry.url}" if entry.url else entry.program
            events_recorded = True
            continue
        last_s = max(last_s, entry.t_s)
        if isinstance(entry, TelemetryEntry):
            if first_s is None:
                first_s = entry.t_s
                series.start_wall_ns = entry.wall_ns
            series.time_s.append(entry.t_s - first_s)
            now_leak = entry.values.get("leak")
            if not events_recorded and now_leak is not None:
                if leak is not None and now_leak != leak:
                    series.events.append((entry.t_s - first_s, "leak"))
                leak = now_leak
            for name, value in entry.values.items():
                series.columns.setdefault(name, []).append(
                    float("nan") if value is None else float(value)
                )
        elif isinstance(entry, EventEntry) and entry.event in _LINK_MARKERS:
            if first_s is None:
                first_s = entry.t_s
                series.start_wall_ns = entry.wall_ns
            state = f"{entry.event} {entry.name}"  # (a link event's name is its state)
            marker = state if entry.event == "link" and state in _LINK_MARKERS else entry.event
            series.events.append((entry.t_s - first_s, marker))
    if first_s is not None and series.time_s and last_s - first_s > series.time_s[-1]:
        # A row holds until the next change, and the last one until the recording ends: a
        # value that never changed, one row, was drawn as nothing at all.
        series.time_s.append(last_s - first_s)
        for values in series.columns.values():
            values.append(values[-1])
    return series


#: The longest span labelled in seconds: an hour's dive read "3500 s" where a pilot thinks in
#: minutes.
_LONGEST_IN_SECONDS_S = 600.0
#: Minute steps for the ticks of a longer span, in seconds.
_MINUTE_STEPS_S = (60.0, 120.0, 300.0, 600.0, 900.0, 1800.0, 3600.0, 7200.0, 21600.0)


def _label_time_axis(axis: Any, span_s: float) -> None:
    """Label the time axis in seconds, or in minutes (ticks at whole minutes) past 10 min."""
    if span_s <= _LONGEST_IN_SECONDS_S:
        axis.set_xlabel("time from the first row, s")
        return
    from matplotlib.ticker import FuncFormatter, MultipleLocator  # noqa: PLC0415

    step_s = next((step for step in _MINUTE_STEPS_S if span_s / step <= 10), _MINUTE_STEPS_S[-1])
    axis.xaxis.set_major_locator(MultipleLocator(step_s))
    axis.xaxis.set_major_formatter(FuncFormatter(lambda seconds, _: f"{seconds / 60:g}"))
    axis.set_xlabel("time from the first row, min")


def _step(axis: Any, series: DiveSeries, column: str, label: str, **style: Any) -> None:
    values = series.columns.get(column)
    if values:
        axis.step(series.time_s, values, where="post", label=label, **style)


#: The figure's size in inches at 100 dpi: a PNG of 1200 × 1100 pixels.
FIGURE_SIZE_IN = (12.0, 11.0)


def plot_dive(entries: Iterable[Entry], *, title: str = "", figure: Any = None) -> Any:
    """A matplotlib figure of the dive in ``entries`` (five panels, one time axis), drawn in
    ``figure`` if given (a window's, for ``--show``); ``title`` (the file's name) is followed
    by who recorded the dive and when it started."""
    return plot_series(collect(entries), title=title, figure=figure)


def plot_series(series: DiveSeries, *, title: str = "", figure: Any = None) -> Any:
    """As :func:`plot_dive`, for the series :func:`collect` took from a recording."""
    from matplotlib.figure import Figure  # noqa: PLC0415 - the plot extra, only when plotting

    if figure is None:
        figure = Figure(figsize=FIGURE_SIZE_IN, dpi=100, layout="constrained")
    depth, thrust, attitude, heading, link = figure.subplots(
        5, 1, sharex=True, height_ratios=[3, 2, 2, 1.5, 1.5]
    )
    _step(depth, series, "depth_cm", "depth", color="tab:blue")
    _step(depth, series, "setpoint_cm", "set-point", color="tab:orange", linestyle="--")
    depth.invert_yaxis()  # deeper is lower, as a pilot sees it
    depth.set_ylabel("depth, cm")
    _step(thrust, series, "vertical_thrust_percent", "vertical (mvs)", color="tab:green")
    _step(thrust, series, "thrust_power_percent", "horizontal power (th)", color="tab:red")
    thrust.set_ylabel("thrust, %")
    direction = thrust.twinx()
    _step(direction, series, "thrust_direction_deg", "direction (th)", color="tab:gray", alpha=0.6)
    direction.set_ylabel("direction, °")
    direction.set_ylim(0, 360)
    _step(attitude, series, "roll_deg", "roll", color="tab:purple")
    _step(attitude, series, "pitch_deg", "pitch", color="tab:cyan")
    attitude.set_ylabel("attitude, °")
    _step(heading, series, "heading_deg", "heading", color="tab:brown")
    heading.set_ylabel("heading, °")
    _step(link, series, "leak", "leak latch", color="tab:red", linewidth=2)
    _step(link, series, "locked", "locked", color="tab:gray")
    link.set_ylim(-0.2, 2.2)
    link.set_yticks([0, 1])
    link.set_ylabel("state")
    labelled: set[str] = set()
    for time_s, event in series.events:
        label, colour = _LINK_MARKERS[event]
        link.axvline(
            time_s,
            color=colour,
            linewidth=1,
            alpha=0.7,
            label=None if label in labelled else label,
        )
        labelled.add(label)
    _label_time_axis(link, max([*series.time_s[-1:], *(time_s for time_s, _ in series.events)]))
    for axis in (depth, thrust, attitude, heading, link):
        axis.grid(True, alpha=0.3)
        handles, labels = axis.get_legend_handles_labels()
        if axis is thrust:
            more_handles, more_labels = direction.get_legend_handles_labels()
            handles, labels = handles + more_handles, labels + more_labels
        if handles:
            # Outside the panel, right of the direction axis: inside, it hid the data under it
            # (the surfacing, at the right of the depth panel).
            axis.legend(
                handles, labels, loc="upper left", bbox_to_anchor=(1.07, 1.0), fontsize="small"
            )
    described = series.describe()
    if title or described:
        figure.suptitle("\n".join(part for part in (title, described) if part))
    return figure
