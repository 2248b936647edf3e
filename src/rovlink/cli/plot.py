"""Plot a recorded dive: depth against set-point, vertical and horizontal thrust, roll, pitch,
heading, the leak latch and the link's events on shared time axes (needs the plot extra:
pip install 'rovlink[plot]')."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Iterator
from typing import TYPE_CHECKING

from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, UsageError
from rovlink.cli.link_options import file_name
from rovlink.cli.output_file import check_image_suffix, save_figure

if TYPE_CHECKING:
    from rovlink.recorder import Entry

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink plot dive.mcap -o dive.png
  rovlink plot dive.csv -o dive.svg
  rovlink plot dive.mcap --show"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``plot``'s arguments."""
    parser.add_argument("file", metavar="FILE", help="a recording (.mcap, .jsonl or .csv)")
    parser.add_argument(
        "-o",
        "--output",
        type=file_name,
        metavar="IMAGE",
        help="write the plot here (.png, .svg, .pdf)",
    )
    parser.add_argument("--show", action="store_true", help="open a window (needs a display)")


def _title(path: str) -> str:
    """The file's name as text: a name that is not UTF-8 (a FAT stick's Latin-1 names) holds
    undecodable bytes as lone surrogates, which the PNG renderer refuses with a traceback.

    >>> _title(os.fsdecode(b"dives/plong\\xe9e.mcap"))
    'plong\ufffde.mcap'
    """
    return os.fsencode(os.path.basename(path)).decode("utf-8", "replace")


#: matplotlib's backends that draw without a window: where it finds no display it can open, or
#: no window toolkit, it falls back to one of them, and its show() then only warns.
_WINDOWLESS_BACKENDS = frozenset({"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"})


def _check_window(display: str | None) -> None:
    """Refuse ``--show`` before anything is read or written where no window can open."""
    from matplotlib import pyplot  # noqa: PLC0415 - picks the backend: a window's, if any works

    if pyplot.get_backend().lower() in _WINDOWLESS_BACKENDS:
        raise CommandError(
            f"--show cannot open a window on display {display} (no display there, or no "
            "window toolkit for matplotlib: tkinter, Qt or GTK); use -o IMAGE"
        )


def run(args: argparse.Namespace) -> int:
    """Draw the dive; damage in the file is reported after the plot of what could be read."""
    if not args.output and not args.show:
        raise UsageError("say where the plot goes: -o IMAGE, --show, or both")
    from rovlink.cli.recording import check_recording_name  # noqa: PLC0415

    check_recording_name(args.file)  # (as replay: a name of no recording format, status 2)
    display = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    if args.show and not display:
        instead = (
            f"without --show the plot is written to {args.output} alone"
            if args.output
            else "use -o IMAGE"
        )
        raise CommandError(f"--show needs a display (none here); {instead}")
    with needs_extra("plot", "plotting needs"):
        import matplotlib  # noqa: PLC0415 - the plot extra, only for this command
    if args.show:
        _check_window(display)
    from rovlink.recorder import RecordingDamagedError, RecordingError, read_entries  # noqa: PLC0415
    from rovlink.recorder.plot import FIGURE_SIZE_IN, collect, plot_series  # noqa: PLC0415

    if args.output:
        check_image_suffix("-o", args.output)
    if not args.show:
        matplotlib.use("Agg")
    damage: RecordingDamagedError | None = None

    def readable() -> Iterator[Entry]:
        nonlocal damage
        try:
            yield from read_entries(args.file)
        except RecordingDamagedError as error:
            damage = error

    # One entry at a time: an hour of 10 Hz qsa held whole took 290 MB (its wire and frames).
    try:
        series = collect(readable())
    except RecordingError as error:
        raise CommandError(str(error)) from None
    except ValueError as error:
        raise UsageError(str(error)) from None
    if not series.time_s:
        if damage is not None:  # the damage, not the kind of file, is why there is none
            raise CommandError(f"{damage}; no telemetry before it to plot")
        raise CommandError(f"{args.file} has no telemetry to plot (a raw capture?)")
    window = None
    if args.show:
        from matplotlib import pyplot  # noqa: PLC0415

        window = pyplot.figure(figsize=FIGURE_SIZE_IN, layout="constrained")
    title = _title(args.file)
    if damage is not None:  # (said on stderr too, but the image is what gets shared)
        title += (
            " (ends early: its recorder was stopped abruptly)"
            if damage.incomplete
            else f" (damaged: plotted up to entry {damage.entries_read})"
        )
    figure = plot_series(series, title=title, figure=window)
    if args.output:
        save_figure(figure, args.output)
        print(f"plotted {args.file} to {args.output}", file=sys.stderr)
    if window is not None:
        pyplot.show()
    if damage is not None:
        print(f"rovlink plot: {damage}", file=sys.stderr)
        return 0 if damage.incomplete else 1
    return 0
