"""``rovlink.connect`` loads the driver on first use; the protocol core stays dependency-free."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytestmark = pytest.mark.integration  # each test starts a Python subprocess


def _run(code: str) -> None:
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_importing_the_protocol_loads_neither_the_driver_nor_pyserial() -> None:
    _run(
        "import sys, rovlink, rovlink.protocol\n"
        "assert 'serial' not in sys.modules, 'pyserial was imported'\n"
        "assert 'rovlink.client' not in sys.modules, 'the driver was imported'\n"
    )


def test_connect_is_available_from_the_top_level_package() -> None:
    _run(
        "import rovlink\n"
        "from rovlink.client import connect, Sensors\n"
        "assert rovlink.connect is connect and rovlink.Sensors is Sensors\n"
    )
