"""``rovlink console`` typed into needs its output on a terminal: else lines run unseen."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from tests.terminals import WAIT_S

_SRC = str(Path(__file__).resolve().parents[2] / "src")


@pytest.mark.integration
@pytest.mark.parametrize("output", ["file", "pipe"])
def test_typed_into_with_its_output_to_a_file_or_a_pipe_it_is_refused_before_the_link_opens(
    tmp_path: Path, output: str
) -> None:
    # Regression: its prompt, replies and toolbar went to the file (or through `| tee`, in
    # pieces) while the keys came from the terminal: start and th typed there ran unseen.
    recording = tmp_path / "dive.jsonl"
    keys, terminal = os.openpty()
    with (
        socket.create_server(("127.0.0.1", 0)) as server,
        (tmp_path / "out.txt").open("wb") as file,
    ):
        server.settimeout(0)
        url = f"socket://127.0.0.1:{server.getsockname()[1]}"
        try:
            result = subprocess.run(
                [sys.executable, "-m", "rovlink", "console", url, "--record", str(recording)],
                stdin=terminal,
                stdout=file if output == "file" else subprocess.PIPE,
                stderr=subprocess.PIPE,
                env={**os.environ, "PYTHONPATH": _SRC},
                timeout=WAIT_S,
                check=False,
            )
        finally:
            os.close(keys)
            os.close(terminal)
        with pytest.raises(BlockingIOError):
            server.accept()  # (nothing connected)
    assert result.returncode == 2
    assert result.stderr.decode() == (
        "rovlink console: typed into, its prompt and replies need a terminal, but standard "
        "output is not one: the lines typed would run unseen; to keep the session, use "
        "--record FILE (lines read from a file may go to one: "
        "rovlink console URL < lines.txt > out.txt)\n"
    )
    assert not recording.exists()
