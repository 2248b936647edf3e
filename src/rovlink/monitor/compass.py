"""The heading as a moving compass tape, and roll and pitch as bars."""

from __future__ import annotations

__all__ = ["attitude_bar", "heading_tape"]

_POINTS = {0: "N", 45: "NE", 90: "E", 135: "SE", 180: "S", 225: "SW", 270: "W", 315: "NW"}


def heading_tape(heading_deg: int, width: int, degrees_per_column: int = 5) -> list[str]:
    """Three lines: the compass points around ``heading_deg``, ticks, and a ▲ under the heading.

    >>> for line in heading_tape(10, 21): print(line)
            N        NE
    ··|··|··┼··|··|··┼··|
              ▲
    """
    width = max(width, 3)
    center = width // 2
    # The columns sit on the degree grid; the one nearest the heading is in the middle.
    middle_deg = round(heading_deg / degrees_per_column) * degrees_per_column
    first_deg = middle_deg - center * degrees_per_column
    labels = [" "] * (width + 2)
    ticks = []
    for column in range(width):
        degrees = first_deg + column * degrees_per_column
        bearing = degrees % 360
        if bearing % 45 == 0:
            ticks.append("┼")
            name = _POINTS[bearing]
            start = max(column - (len(name) - 1) // 2, 0)
            labels[start : start + len(name)] = name
        elif bearing % 15 == 0:
            ticks.append("|")
        else:
            ticks.append("·")
    marker = " " * center + "▲"
    return ["".join(labels[:width]).rstrip(), "".join(ticks).rstrip(), marker]


def attitude_bar(angle_deg: int, width: int = 21, limit_deg: int = 90) -> str:
    """A bar from −``limit_deg`` to +``limit_deg`` with ``┼`` at 0 and ``●`` at the angle.

    >>> attitude_bar(45, width=9)
    '────┼─●──'
    """
    width = max(width | 1, 3)  # odd, so 0 has a middle column
    center = width // 2
    clamped = max(-limit_deg, min(limit_deg, angle_deg))
    column = center + round(clamped / limit_deg * center)
    bar = ["─"] * width
    bar[center] = "┼"
    bar[column] = "●"
    return "".join(bar)
