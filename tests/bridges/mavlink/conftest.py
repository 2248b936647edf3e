"""Fixtures: a MAVLink bridge on the simulator and a pymavlink ground station."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

pytest.importorskip("pymavlink", reason="needs pymavlink: pip install 'rovlink[mavlink]'")

from tests.bridges.mavlink.rig import BridgeRig, GroundStation, running_bridge


@pytest.fixture
def rig() -> Iterator[BridgeRig]:
    with running_bridge() as bridge_rig:
        yield bridge_rig


@pytest.fixture
def gcs(rig: BridgeRig) -> Iterator[GroundStation]:
    station = GroundStation(rig.gcs_address)
    try:
        station.receive("HEARTBEAT", condition=lambda m: m.type == 12)
        station.heartbeat()
        yield station
    finally:
        station.close()
