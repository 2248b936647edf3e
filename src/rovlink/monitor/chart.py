"""Depth over time as lines of text: depth grows downwards, the target is a dotted line."""

from __future__ import annotations

import math
from collections.abc import Iterable

from rovlink.monitor.readings import DepthSample

__all__ = ["SAMPLE_MARK", "TARGET_MARK", "depth_chart"]

SAMPLE_MARK = "•"
TARGET_MARK = "┈"
#: The depth scale never shrinks below this, so a robot at the surface is not all noise.
_MIN_SCALE_CM = 50
_LABEL_WIDTH = 7  # "9999 cm"


def _nice_ceiling(value_cm: float) -> int:
    """The smallest of 1, 2 or 5 × 10^n that is at least ``value_cm``.

    >>> _nice_ceiling(123), _nice_ceiling(50), _nice_ceiling(501)
    (200, 50, 1000)
    """
    exponent = math.floor(math.log10(value_cm))
    for factor in (1, 2, 5, 10):
        nice = factor * 10**exponent
        if nice >= value_cm:
            return int(nice)
    raise AssertionError("unreachable")  # pragma: no cover


def depth_chart(
    samples: Iterable[DepthSample],
    *,
    now_s: float,
    window_s: float,
    width: int,
    height: int,
    target_cm: int | None = None,
) -> list[str]:
    """The last ``window_s`` seconds of depth as ``height`` + 2 lines of ``width`` characters.

    Columns are time (now at the right), rows depth (the surface at the top); each sample is a
    dot, the target a dotted line. The scale grows to fit the deepest sample and the target.

    >>> lines = depth_chart([DepthSample(9.0, 20)], now_s=10.0, window_s=10.0, width=20,
    ...                     height=3, target_cm=40)
    >>> print("\\n".join(lines))
       0 cm│
      25 cm│          •
      50 cm│┈┈┈┈┈┈┈┈┈┈┈┈
           └────────────
            -10 s    now
    """
    plot_width = max(width - _LABEL_WIDTH - 1, 1)
    height = max(height, 2)
    start_s = now_s - window_s
    visible = [sample for sample in samples if start_s <= sample.at_s <= now_s]
    deepest_cm = max((sample.depth_cm for sample in visible), default=0)
    scale_cm = _nice_ceiling(max(deepest_cm, target_cm or 0, _MIN_SCALE_CM))
    rows = [[" "] * plot_width for _ in range(height)]

    def row_of(depth_cm: int) -> int:
        return min(round(depth_cm / scale_cm * (height - 1)), height - 1)

    if target_cm is not None:
        rows[row_of(target_cm)] = [TARGET_MARK] * plot_width
    for sample in visible:
        column = min(int((sample.at_s - start_s) / window_s * plot_width), plot_width - 1)
        rows[row_of(sample.depth_cm)][column] = SAMPLE_MARK
    lines = []
    for index, row in enumerate(rows):
        label_cm = round(index * scale_cm / (height - 1))
        label = f"{label_cm} cm" if index in (0, height // 2, height - 1) else ""
        lines.append(f"{label:>{_LABEL_WIDTH}}│" + "".join(row).rstrip())
    lines.append(" " * _LABEL_WIDTH + "└" + "─" * plot_width)
    left = f"-{window_s:g} s"
    lines.append(" " * (_LABEL_WIDTH + 1) + left + "now".rjust(plot_width - len(left)))
    return lines
