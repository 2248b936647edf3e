"""Fixtures: a controller on fake hardware (see controller_rig)."""

from __future__ import annotations

import pytest

from tests.controller.controller_rig import Rig, make_rig


@pytest.fixture
def rig() -> Rig:
    return make_rig()


@pytest.fixture
def debug_rig() -> Rig:
    rig = make_rig()
    rig.send(b"#debug1!")
    return rig


@pytest.fixture
def armed_rig() -> Rig:
    """Unlocked, with the watchdog off so long runs need no keep-alive."""
    rig = make_rig(watchdog_s=0.0)
    rig.send(b"#start!")
    return rig
