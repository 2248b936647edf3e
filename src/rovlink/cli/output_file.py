"""An output file named on the command line is checked before the command's work, not after
it: ``check --junit`` runs for most of a minute, ``tune --plot`` for minutes with the motors
running, and a name that cannot be written would be found only at the end."""

from __future__ import annotations

import os
from pathlib import Path

from rovlink.cli.failure import UsageError

__all__ = ["check_image_suffix", "check_writable"]


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
