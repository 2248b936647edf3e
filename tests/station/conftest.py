"""Fixtures of the web station's tests: a recorded simulated robot and ``rovlink web`` on it."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from tests.station.rig import ControllerLine, StationProcess, running_station


@pytest.fixture
def line() -> Iterator[ControllerLine]:
    robot = ControllerLine()
    yield robot
    robot.close()


@pytest.fixture
def station(line: ControllerLine) -> Iterator[StationProcess]:
    with running_station(line.url) as process:
        yield process


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The screenshots of the docs are retaken on demand (``ROVLINK_SCREENSHOTS=1``), and
    otherwise deselected rather than skipped: in CI a skipped test fails the run."""
    if os.environ.get("ROVLINK_SCREENSHOTS") == "1":
        return
    retaking = [item for item in items if item.get_closest_marker("screenshots") is not None]
    if retaking:
        config.hook.pytest_deselected(items=retaking)
        items[:] = [item for item in items if item.get_closest_marker("screenshots") is None]
