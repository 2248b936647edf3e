"""``rovlink web``'s command line: one-line errors before anything is served."""

from __future__ import annotations

import argparse
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from rovlink.cli import main, web


def test_a_short_token_is_a_usage_error(capsys):
    assert main(["web", "--host", "0.0.0.0", "--token", "short"]) == 2
    assert "--token must be at least 8 characters" in capsys.readouterr().err


def test_a_bad_url_is_a_usage_error(capsys):
    assert main(["web", "sim://?speed=3"]) == 2
    assert "unknown sim option 'speed'" in capsys.readouterr().err


def test_a_bad_url_leaves_no_recording(capsys, tmp_path):
    recording = tmp_path / "badurl.mcap"
    assert main(["web", "sim://?speed=3", "--record", str(recording)]) == 2
    assert "unknown sim option 'speed'" in capsys.readouterr().err
    assert not recording.exists()


@pytest.mark.integration
def test_a_taken_port_is_one_line(capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        assert main(["web", "sim://", "--port", str(port)]) == 1
    error = capsys.readouterr().err.strip()
    assert error == f"rovlink web: cannot serve on 127.0.0.1:{port}: Address already in use"


def test_the_port_and_rate_are_checked(capsys):
    assert main(["web", "--port", "70000"]) == 2
    assert "70000 is not in 0–65535" in capsys.readouterr().err
    assert main(["web", "--rate", "0"]) == 2
    assert "less than the minimum" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["--help"], ["web", "--help"]])
def test_help_names_the_station(argv, capsys):
    assert main(argv) == 0
    assert "web" in capsys.readouterr().out


@pytest.mark.integration
def test_the_help_loads_no_web_library():
    script = "import sys\nfrom rovlink.cli import main\nmain(['web', '--help'])\n"
    check = (
        "import atexit, sys\n"
        "atexit.register(lambda: print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('starlette', 'uvicorn', 'websockets', 'serial') or m.startswith('rovlink.station'))"
        ", file=sys.stderr))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", check + script],
        check=False,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 0
    assert result.stderr.strip().splitlines()[-1] == "[]"


def test_every_option_is_in_the_docs_options_table():
    parser = argparse.ArgumentParser()
    web.add_arguments(parser)
    options = {
        option
        for action in parser._actions
        for option in action.option_strings
        if option.startswith("--") and option not in ("--help", "--no-checksum")
    }
    docs = (Path(__file__).resolve().parents[2] / "docs" / "station.md").read_text()
    table = [line for line in docs.splitlines() if line.startswith("| `")]
    documented = {word.strip("`,") for line in table for word in line.split("|")[1].split()}
    assert options - documented == set()


@pytest.mark.parametrize(
    ("argv", "algorithm"),
    [(["sim://?algorithm=xor"], "xor"), (["sim://", "--algorithm", "sum8"], "sum8")],
    ids=["the URL's", "the option's"],
)
def test_the_station_names_the_simulators_algorithm(
    monkeypatch: pytest.MonkeyPatch, argv: list[str], algorithm: str
) -> None:
    # The station was given crc8 for a sim://?algorithm=xor link: its options were made
    # before the URL's algorithm was taken.
    from rovlink.station import serve as station_serve
    from rovlink.station.serve import ServeOptions

    served: list[tuple[ServeOptions, str]] = []

    async def serve(connect: object, options: ServeOptions, **kwargs: object) -> bool:
        served.append((options, str(kwargs["description"])))
        return False

    monkeypatch.setattr(station_serve, "serve", serve)
    assert main(["web", *argv, "--port", "0"]) == 0
    [(options, url)] = served
    assert options.algorithm == algorithm
    assert url == f"sim://?algorithm={algorithm}"


@pytest.mark.integration
def test_a_station_whose_polls_fail_ends_with_status_1(capsys, monkeypatch, tmp_path):
    # Before, a station whose polling (or watchdog) task failed logged the traceback, shut down
    # and exited with 0: a service manager took it for a clean stop and did not restart it.
    async def failing_poll(self):
        raise RuntimeError("a bug in the polls")

    monkeypatch.setattr("rovlink.station.hub.Station._poll", failing_poll)
    assert main(["web", "--port", "0", "--recordings", str(tmp_path)]) == 1
    said = capsys.readouterr().err.strip().splitlines()[-1]
    assert said == (
        "rovlink web: the station's polling or watchdog failed (RuntimeError: a bug in the "
        "polls): the station shut down"
    )
