"""An output file named on the command line is checked before the command's work, not after
it: ``check --junit`` runs for most of a minute, ``tune --plot`` for minutes with the motors
running, and a name that cannot be written would be found only at the end. What fails still at
the end (a full disk, a format needing a program not installed) is one line, with no part of the
file left (:func:`save_figure`)."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import TYPE_CHECKING

from rovlink.cli.failure import CommandError, UsageError, reason

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["check_image_suffix", "check_writable", "save_figure"]


def check_writable(option: str, path: str) -> None:
    """A usage error naming ``option`` unless ``path`` can be written: its directory must exist
    and be writable, and ``path`` must not be a directory."""
    target = Path(path)
    directory = target.parent
    if target.is_dir():
        raise UsageError(f"{option} {path}: is a directory")
    if not directory.exists():
        raise UsageError(f"{option} {path}: no such directory: {directory}")
    if not directory.is_dir():
        raise UsageError(f"{option} {path}: not a directory: {directory}")
    if not os.access(target if target.exists() else directory, os.W_OK):
        raise UsageError(f"{option} {path}: not writable")


def check_image_suffix(option: str, path: str) -> None:
    """A usage error naming ``option`` unless ``path``'s suffix is an image format matplotlib
    writes: it would add ``.png`` to a name without one and write another file than the one
    named (or, after ``dir/``, a hidden ``dir/.png``), and refuse one it does not know."""
    from matplotlib.backend_bases import FigureCanvasBase  # noqa: PLC0415 - the plot extra

    formats = FigureCanvasBase.get_supported_filetypes()
    if os.path.splitext(path)[1].lower().lstrip(".") not in formats:
        common = [name for name in ("png", "svg", "pdf") if name in formats]
        others = sorted(set(formats) - set(common))
        known = ", ".join(f".{name}" for name in common + others)
        raise UsageError(f"{option} {path}: name the image format by its suffix: {known}")


def save_figure(figure: Figure, path: str) -> None:
    """Write ``figure`` to ``path``; a failure is a :class:`CommandError` of one line, and
    leaves no part of an image there (a truncated PNG opens as a broken one, or as a plot that
    ends early)."""
    try:
        figure.savefig(path)
    except (OSError, ValueError, RuntimeError) as error:
        # (RuntimeError: a format that needs a program not installed, .pgf's LaTeX)
        if os.path.isfile(path) and not os.path.islink(path):
            with contextlib.suppress(OSError):
                os.remove(path)
        why = str(error) if isinstance(error, RuntimeError) else reason(error)  # (its own words)
        raise CommandError(f"cannot write {path}: {why}") from None
