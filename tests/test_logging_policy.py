"""The library logs without printing: a program that configures no logging sees nothing."""

from __future__ import annotations

import subprocess
import sys

import pytest

pytestmark = pytest.mark.integration


def test_an_unconfigured_program_gets_no_rovlink_log_lines_on_stderr() -> None:
    code = (
        "import logging, rovlink.client\n"
        "logging.getLogger('rovlink.client').warning('a dropped frame')\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stderr == ""


def test_a_configured_program_gets_the_log_lines() -> None:
    code = (
        "import logging, rovlink.client\n"
        "logging.basicConfig(format='%(name)s %(message)s')\n"
        "logging.getLogger('rovlink.client').warning('a dropped frame')\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stderr == "rovlink.client a dropped frame\n"
