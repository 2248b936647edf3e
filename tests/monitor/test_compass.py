"""Heading tape and attitude bars."""

from __future__ import annotations

import pytest

from rovlink.monitor.compass import attitude_bar, heading_tape


@pytest.mark.parametrize(
    ("heading_deg", "point"), [(0, "N"), (90, "E"), (180, "S"), (270, "W"), (360, "N"), (135, "SE")]
)
def test_the_point_under_the_marker_is_the_heading(heading_deg: int, point: str) -> None:
    labels, ticks, marker = heading_tape(heading_deg, 31)
    center = marker.index("▲")
    assert center == 15
    assert ticks[center] == "┼"
    assert (
        labels[center : center + len(point)].strip() == point
        or labels[center - 1 : center + 1] == point
    )


def test_the_tape_moves_with_the_heading() -> None:
    labels_at_0 = heading_tape(0, 31)[0]
    labels_at_10 = heading_tape(10, 31)[0]
    assert labels_at_0.index("N") - labels_at_10.index("N") == 2  # 5° per column


def test_attitude_bar() -> None:
    assert attitude_bar(0, width=9) == "────●────"
    assert attitude_bar(-90, width=9) == "●───┼────"
    assert attitude_bar(90, width=9) == "────┼───●"
    assert attitude_bar(400, width=9) == attitude_bar(90, width=9)
