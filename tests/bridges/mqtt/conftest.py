"""Fixtures: a real mosquitto broker for the MQTT bridge's tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("aiomqtt", reason="needs aiomqtt: pip install 'rovlink[mqtt]'")

from tests.bridges.mqtt.broker import Mosquitto, running_broker


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    yield from running_broker(tmp_path)
