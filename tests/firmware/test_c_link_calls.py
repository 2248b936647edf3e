"""The protocol layer's calls that a byte stream alone cannot exercise, stepped by a script
(``link_steps.c``), built strictly and under the sanitizers."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.firmware.c_build import LAYER, SANITIZE, STRICT, build, needs_gcc, run_script

STEPS = Path(__file__).resolve().parent / "link_steps.c"
pytestmark = [pytest.mark.integration, needs_gcc]


@pytest.fixture(scope="module")
def steps(tmp_path_factory: pytest.TempPathFactory) -> Path:
    output = tmp_path_factory.mktemp("link_steps") / "link_steps"
    return build(output, [STEPS, *LAYER], *STRICT, *SANITIZE)


def _feed(data: bytes) -> str:
    return "feed " + data.hex()


def test_bytes_lost_in_a_frame_drop_it_rather_than_splice_it_with_the_next(steps: Path) -> None:
    # "#th.270.25!#th.0.0!" with "5!#th.0." lost in a receive overrun would read as
    # "#th.270.20!": the zero power the host sent would become 20 %.
    script = [_feed(b"#start!#th.270.2"), "lost", _feed(b"0!#th.0.0!")]
    lines = [" ".join(words) for words in run_script(steps, script)]
    assert [line for line in lines if line.startswith("C ")][-1] == "C th 0 0"
    assert not any(line.startswith("C th 270") for line in lines)
    assert "D dropped <th.270.2>: bytes lost in it (receive overrun)" in lines


def test_bytes_lost_between_frames_drop_nothing(steps: Path) -> None:
    script = [_feed(b"#start!"), "lost", _feed(b"#th.90.10!"), "lost", "lost"]
    lines = [" ".join(words) for words in run_script(steps, script)]
    assert "C th 90 10" in lines
    assert not any("dropped" in line for line in lines)


def test_a_stop_reaches_the_app_before_its_line_is_written(steps: Path) -> None:
    # On a slow line the write of a debug line may wait for room (an Uno's 64-byte buffer):
    # the app's outputs go to neutral first, then the line is written.
    script = [_feed(b"#start!#th.90.10!#stop!")]
    lines = [" ".join(words) for words in run_script(steps, script)]
    stop_at = lines.index("C stop")
    assert lines[stop_at + 1] == "D stop command: motors stopped and locked"
