"""Fixtures of the web station's tests: a recorded simulated robot and ``rovlink web`` on it."""

from __future__ import annotations

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
