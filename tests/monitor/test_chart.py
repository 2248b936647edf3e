"""The depth chart: time across, depth down, the target dotted, the scale fitting the data."""

from __future__ import annotations

from rovlink.monitor.chart import SAMPLE_MARK, TARGET_MARK, depth_chart
from rovlink.monitor.readings import DepthSample


def _plot(lines: list[str]) -> list[str]:
    """The plot area of each row (after the axis)."""
    return [line.split("│", 1)[1] if "│" in line else "" for line in lines[:-2]]


def test_samples_fall_in_their_time_column_and_depth_row() -> None:
    samples = [DepthSample(at_s, depth_cm) for at_s, depth_cm in ((0.0, 0), (5.0, 25), (9.99, 50))]
    lines = depth_chart(samples, now_s=10.0, window_s=10.0, width=18, height=3)
    rows = _plot(lines)
    assert rows[0].index(SAMPLE_MARK) == 0  # oldest, at the surface: top left
    assert rows[1].index(SAMPLE_MARK) == 5  # half way across, half way down
    assert rows[2].rstrip().endswith(SAMPLE_MARK)  # newest, deepest: bottom right
    assert lines[0].startswith("   0 cm│")
    assert lines[2].startswith("  50 cm│")
    assert all(len(line) <= 18 for line in lines)


def test_the_scale_grows_to_the_deepest_sample_or_the_target() -> None:
    deep = depth_chart([DepthSample(1.0, 430)], now_s=2.0, window_s=10.0, width=30, height=5)
    assert deep[-3].startswith(" 500 cm│")
    target = depth_chart([], now_s=2.0, window_s=10.0, width=30, height=5, target_cm=1200)
    assert target[-3].startswith("2000 cm│")
    assert TARGET_MARK * 5 in "".join(target)


def test_samples_outside_the_window_are_left_out() -> None:
    lines = depth_chart([DepthSample(0.0, 10)], now_s=100.0, window_s=60.0, width=30, height=4)
    assert SAMPLE_MARK not in "".join(lines)
    assert lines[-1].split() == ["-60", "s", "now"]


def test_the_target_line_and_a_sample_share_a_row() -> None:
    lines = depth_chart(
        [DepthSample(9.5, 40)], now_s=10.0, window_s=10.0, width=28, height=6, target_cm=40
    )
    (row,) = [row for row in _plot(lines) if TARGET_MARK in row]
    assert row.count(SAMPLE_MARK) == 1
    assert row.count(TARGET_MARK) == 19
