"""``rovlink plot -o IMAGE`` that cannot write its image: one line naming it, and no part of an
image left behind."""

from __future__ import annotations

from pathlib import Path

import pytest

import rovlink
from rovlink.recorder import Recorder
from tests.cli.conftest import RunCli

pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")


@pytest.fixture
def recording(tmp_path: Path) -> Path:
    path = tmp_path / "dive.jsonl"
    recorder = Recorder(str(path), url="sim://?seed=1&realtime=0")
    with recorder, rovlink.connect("sim://?seed=1&realtime=0", on_event=recorder.on_event) as rov:
        rov.start()
        rov.hold_depth(30)
        for _ in range(5):
            rov.sensors()
        rov.stop()
    return path


@pytest.mark.integration
def test_a_format_whose_program_is_missing_is_one_line(
    run_cli: RunCli, recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, a traceback: matplotlib's .pgf needs LaTeX ("'xelatex' not found").
    monkeypatch.setenv("PATH", str(tmp_path))  # (no LaTeX there, installed or not)
    image = tmp_path / "dive.pgf"
    result = run_cli("plot", str(recording), "-o", str(image))
    assert result.status == 1
    assert result.err.startswith(f"rovlink plot: cannot write {image}: ")
    assert "not found" in result.err
    assert "Traceback" not in result.err
    assert not image.exists()


def test_an_image_cut_short_is_not_left_behind(
    run_cli: RunCli, recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, the half-written PNG of a disk that filled up stayed, named as the plot.
    from matplotlib.figure import Figure  # (the plot extra)

    def fill_up(self: Figure, path: str, **kwargs: object) -> None:
        Path(path).write_bytes(b"\x89PNG\r\n\x1a\n")  # its start, and then the disk was full
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", fill_up)
    image = tmp_path / "dive.png"
    result = run_cli("plot", str(recording), "-o", str(image))
    assert result.status == 1
    assert result.err == f"rovlink plot: cannot write {image}: No space left on device\n"
    assert not image.exists()


def test_a_recording_cut_short_says_so_on_the_image(
    run_cli: RunCli, recording: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Only stderr said that the recording ends early; the image, which is what is passed
    # round, looked like a whole dive.
    from matplotlib.figure import Figure  # (the plot extra)

    titles: list[str] = []
    monkeypatch.setattr(
        Figure, "savefig", lambda self, *_, **__: titles.append(self.get_suptitle())
    )
    data = recording.read_bytes()
    recording.write_bytes(data[: data.rindex(b"\n", 0, len(data) - 1) + 20])  # a killed recorder
    result = run_cli("plot", str(recording), "-o", str(tmp_path / "dive.png"))
    assert result.status == 0
    assert "ends in the middle of line" in result.err
    assert titles[0].startswith("dive.jsonl (ends early: its recorder was stopped abruptly)\n")


def test_a_csv_cut_between_two_rows_says_so(
    run_cli: RunCli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A telemetry table whose recorder was killed between two rows plotted as a whole dive.
    from matplotlib.figure import Figure  # (the plot extra)

    titles: list[str] = []
    monkeypatch.setattr(
        Figure, "savefig", lambda self, *_, **__: titles.append(self.get_suptitle())
    )
    path = tmp_path / "dive.csv"
    recorder = Recorder(str(path), url="sim://?seed=1&realtime=0")
    with recorder, rovlink.connect("sim://?seed=1&realtime=0", on_event=recorder.on_event) as rov:
        rov.start()
        rov.hold_depth(30)
        for _ in range(5):
            rov.sensors()
        rov.stop()
    rows = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join(rows[:-2]))  # a recorder killed after a flush
    result = run_cli("plot", str(path), "-o", str(tmp_path / "dive.png"))
    assert result.status == 0
    assert result.err.splitlines()[-1] == (
        f"rovlink plot: {path}: the recording ends early, without its closing row (its "
        f"recorder was stopped abruptly); read {len(rows) - 3} rows"
    )
    assert titles[0].startswith("dive.csv (ends early: its recorder was stopped abruptly)\n")
