"""The picture of a dive: what it marks and what its title says, from entries made by hand."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from rovlink.recorder import (
    Entry,
    EventEntry,
    FrameEntry,
    HeaderEntry,
    TelemetryEntry,
    read_entries,
)
from rovlink.recorder.entries import TELEMETRY_FIELDS
from rovlink.recorder.formats import open_sink
from rovlink.recorder.plot import collect, plot_dive

pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")

#: 2026-11-27 19:07:12 UTC, in ns since the Unix epoch.
_START_WALL_NS = 1_795_806_432_000_000_000


def _row(t_s: float, *, leak: int) -> TelemetryEntry:
    wall_ns = _START_WALL_NS + round((t_s - 100.0) * 1e9)
    return TelemetryEntry(t_s, wall_ns, {"depth_cm": 80, "leak": leak, "locked": 0})


def _dive_ending_in_a_leak() -> list[Entry]:
    """A dive whose last reply latched the leak, as a demo aborted by a leak ends."""
    header = HeaderEntry(99.9, _START_WALL_NS - 100_000_000, "sim://", False, "crc8", "demo", "1")
    fired = EventEntry(105.0, _START_WALL_NS + 5_000_000_000, "leak", "q.l", "leak latch fired")
    return [header, _row(100.0, leak=0), _row(102.5, leak=0), fired, _row(105.0, leak=1)]


def _state_panel_lines(figure: Any) -> dict[str, list[Any]]:
    lines: dict[str, list[Any]] = {}
    (state,) = (axis for axis in figure.axes if axis.get_ylabel() == "state")
    for line in state.get_lines():
        lines.setdefault(line.get_label(), []).append(line)
    return lines


def test_a_leak_is_marked_where_it_fired() -> None:
    # A leak latched by the dive's last reply was drawn as nothing: the latch's step starts at
    # the last row, and leak events were not among the marked ones.
    figure = plot_dive(_dive_ending_in_a_leak())
    marks = _state_panel_lines(figure)["leak latch change"]
    assert [list(mark.get_xdata()) for mark in marks] == [[5.0, 5.0]]


def test_a_leak_in_a_table_without_events_is_marked_where_it_fired() -> None:
    # A .csv holds no leak event: a dive aborted by a leak showed it only as a step of the
    # latch at the last row, at the right edge of the picture.
    rows = [_row(100.0, leak=0), _row(102.5, leak=0), _row(105.0, leak=1), _row(105.1, leak=1)]
    assert collect(rows).events == [(5.0, "leak")]
    assert collect(_dive_ending_in_a_leak()).events == [(5.0, "leak")]  # (its event, once)


def test_the_title_says_who_recorded_the_dive_and_when_it_started() -> None:
    # The image said only the file's name: a plot passed round a week later said neither when
    # nor on what.
    figure = plot_dive(_dive_ending_in_a_leak(), title="dive.mcap")
    assert figure.get_suptitle() == "dive.mcap\ndemo on sim://, started 2026-11-27 19:07:12 UTC"


def test_a_csv_without_a_header_still_says_when() -> None:
    series = collect([_row(100.0, leak=0)])
    assert series.describe() == "started 2026-11-27 19:07:12 UTC"


def test_a_damaged_wall_clock_leaves_the_start_out_of_the_title() -> None:
    series = collect([TelemetryEntry(1.0, 10**30, {"depth_cm": 80})])
    assert series.describe() == ""


def test_a_value_that_never_changed_is_drawn_to_the_recordings_end() -> None:
    # Telemetry is a row per change: a depth that stayed 0 through a 7 s recording was one row,
    # and its panel was empty.
    row = TelemetryEntry(100.0, _START_WALL_NS, {"depth_cm": 0})
    query = FrameEntry(107.0, _START_WALL_NS + 7_000_000_000, "out", "command", "qd", ())
    series = collect([row, query])
    assert (series.time_s, series.columns) == ([0.0, 7.0], {"depth_cm": [0.0, 0.0]})
    (depth,) = (axis for axis in plot_dive([row, query]).axes if axis.get_ylabel() == "depth, cm")
    assert [list(line.get_xdata()) for line in depth.get_lines()] == [[0.0, 7.0]]


@pytest.mark.parametrize("suffix", [".csv", ".jsonl", ".mcap"])
def test_a_recording_is_plotted_to_its_end_in_every_format(tmp_path: Path, suffix: str) -> None:
    # A .csv holds a row per change, and its reader dropped the closing row that says when the
    # recording ended: a dive's last minute at one depth was plotted as none (and a value that
    # never changed, one row, as nothing), where its .mcap and .jsonl went to the end.
    path = str(tmp_path / f"dive{suffix}")
    sink = open_sink(path)
    sink.write(HeaderEntry(99.9, _START_WALL_NS, "sim://", False, "crc8", "demo", "1"))
    row = _row(100.0, leak=0)
    sink.write(
        TelemetryEntry(row.t_s, row.wall_ns, {**dict.fromkeys(TELEMETRY_FIELDS), **row.values})
    )
    sink.write(FrameEntry(160.0, _START_WALL_NS + 60 * 10**9, "out", "command", "qd", ()))
    sink.close()
    assert collect(read_entries(path)).time_s == [0.0, 60.0]


def test_no_legend_hides_the_data_of_its_panel() -> None:
    # In the panel's upper right corner, the depth legend covered the surfacing at a dive's end.
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    figure = plot_dive(_dive_ending_in_a_leak())
    renderer = FigureCanvasAgg(figure).get_renderer()
    figure.draw(renderer)
    legends = [(axis, axis.get_legend()) for axis in figure.axes if axis.get_legend()]
    assert len(legends) == 2  # (the depth panel's, the state panel's: only they have data)
    for axis, legend in legends:
        panel = axis.get_window_extent(renderer)
        assert not legend.get_window_extent(renderer).overlaps(panel), axis.get_ylabel()


def test_a_lost_link_and_its_return_are_told_apart() -> None:
    lost = EventEntry(101.0, _START_WALL_NS + 10**9, "link", "lost", "tcp: closed; reconnecting")
    back = EventEntry(104.0, _START_WALL_NS + 4 * 10**9, "link", "reconnected", "after 6 attempts")
    figure = plot_dive([_row(100.0, leak=0), lost, back, _row(105.0, leak=0)])
    marks = _state_panel_lines(figure)
    assert [list(mark.get_xdata()) for mark in marks["link lost"]] == [[1.0, 1.0]]
    assert [list(mark.get_xdata()) for mark in marks["link reconnected"]] == [[4.0, 4.0]]


def test_an_hour_is_labelled_in_minutes() -> None:
    # It read "3500" on an axis of seconds.
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    figure = plot_dive([_row(100.0, leak=0), _row(3700.0, leak=0)])
    FigureCanvasAgg(figure).draw()
    state = figure.axes[4]
    assert state.get_xlabel() == "time from the first row, min"
    ticks = [label.get_text() for label in state.get_xticklabels()]
    assert {"0", "30", "60"} <= set(ticks)


def test_ten_minutes_are_labelled_in_seconds() -> None:
    figure = plot_dive([_row(100.0, leak=0), _row(700.0, leak=0)])
    assert figure.axes[4].get_xlabel() == "time from the first row, s"


def test_the_header_is_no_end_of_the_recording() -> None:
    # (A header on another clock than its entries, as a program feeding made-up times writes.)
    header = HeaderEntry(9999.0, _START_WALL_NS, "", False, "crc8", "bench", "1")
    series = collect([header, _row(100.0, leak=0), _row(101.0, leak=0)])
    assert (series.time_s, series.recorded_by) == ([0.0, 1.0], "bench")
