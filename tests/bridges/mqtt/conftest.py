"""Fixtures: a real mosquitto broker for the MQTT bridge's tests."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("aiomqtt", reason="needs aiomqtt: pip install 'rovlink[mqtt]'")

from tests.bridges.mqtt.broker import Mosquitto, mosquitto_available


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[Mosquitto]:
    if not mosquitto_available():
        pytest.skip("needs mosquitto (Debian package mosquitto)")
    mosquitto = Mosquitto(tmp_path)
    mosquitto.start()
    try:
        yield mosquitto
    finally:
        mosquitto.stop()
