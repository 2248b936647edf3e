"""The Pi's hardware libraries load only when a device is opened, and only for --board pi."""

from __future__ import annotations

import subprocess
import sys

import pytest

from tests.board.controller_process import environment
from tests.board.rig import EXAMPLE

pytestmark = pytest.mark.integration

_HARDWARE = ("smbus2", "gpiozero", "adafruit_bno055", "adafruit_bus_device", "board", "busio")


def _loaded_after(code: str) -> set[str]:
    program = code + "\nimport sys\nprint(' '.join(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", program],
        capture_output=True,
        text=True,
        env=environment(),
        timeout=60,
        check=True,
        cwd=EXAMPLE.parents[1],  # the repository root: tests.board is importable
    )
    return set(result.stdout.split()) & set(_HARDWARE)


def test_the_board_package_and_its_config_load_no_hardware_library() -> None:
    assert (
        _loaded_after(
            "import rovlink.board.server, rovlink.board.pi.board\n"
            "from rovlink.board.pi.config import load_pi_config\n"
            f"load_pi_config({str(EXAMPLE)!r})"
        )
        == set()
    )


def test_the_controller_command_loads_no_hardware_library_until_it_runs() -> None:
    assert _loaded_after("import rovlink.cli.controller, rovlink.controller") == set()


def test_a_fake_board_loads_only_gpiozero_and_the_bno055_driver() -> None:
    loaded = _loaded_after(
        "from rovlink.board.pi.board import open_pi_board\n"
        "from tests.board.rig import example_config\n"
        "open_pi_board(example_config()).close()"
    )
    assert "smbus2" not in loaded  # the fake bus stands in for it
    assert {"gpiozero", "adafruit_bno055"} <= loaded
