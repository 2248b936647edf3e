"""Settings for the whole suite."""

from __future__ import annotations

from hypothesis import settings

# Property tests check results, not speed: on a loaded machine one example can take longer than
# Hypothesis's default deadline of 200 ms, which would fail the run through no fault of the code.
settings.register_profile("rovlink", deadline=None)
settings.load_profile("rovlink")
