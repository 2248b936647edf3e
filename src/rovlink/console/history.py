"""Where the console keeps its input history between sessions: the user's state directory."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["HISTORY_FILE_NAME", "default_history_path"]

HISTORY_FILE_NAME = "console_history"


def default_history_path() -> Path:
    """``<user state dir>/rovlink/console_history``.

    The state directory is platformdirs' (``$XDG_STATE_HOME`` or ``~/.local/state`` on Linux)
    when platformdirs is installed, else ``$XDG_STATE_HOME`` or ``~/.local/state``.
    """
    try:
        import platformdirs  # noqa: PLC0415 - optional: the console works without it
    except ImportError:
        state_home = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
        return Path(state_home) / "rovlink" / HISTORY_FILE_NAME
    return Path(platformdirs.user_state_dir("rovlink")) / HISTORY_FILE_NAME
