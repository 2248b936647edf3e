"""A simulation running faster than real time really pauses between batches.

``time.sleep(0)`` does not sleep on Python 3.10 (it does, for the timer slack, on 3.11+): the
simulation thread then took its lock straight back, and a query to ``sim://?realtime=0`` waited
100-200 ms now and then for a reply already computed, enough to time out under load.
"""

from __future__ import annotations

import threading
import time

import pytest

from rovlink.sim import open_port


def test_the_fast_simulation_sleeps_a_positive_time_between_batches(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    pauses_s: list[float] = []
    enough = threading.Event()
    real_sleep = time.sleep

    def recording_sleep(seconds: float) -> None:
        pauses_s.append(seconds)
        if len(pauses_s) >= 5:
            enough.set()
        real_sleep(seconds)

    # The simulation thread calls time.sleep through the module, so patching it there is seen.
    monkeypatch.setattr(time, "sleep", recording_sleep)
    with open_port(seed=1, realtime=False):
        assert enough.wait(timeout=10), "the simulation thread never paused"
    assert min(pauses_s[:5]) > 0
