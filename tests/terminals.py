"""Terminals as another program sees them."""

from __future__ import annotations

import os
import subprocess


def open_as_another_user(device: str) -> str:
    """Open ``device`` from a shell of another user (nobody, when the tests run as root, since
    root passes a terminal's exclusive mode); what the shell said: "opened", or its error."""
    command = ["/bin/sh", "-c", 'exec 3<>"$0" && echo opened', device]
    user = 65534 if os.geteuid() == 0 else None
    result = subprocess.run(
        command, capture_output=True, text=True, timeout=30, check=False, user=user
    )
    return result.stdout + result.stderr
