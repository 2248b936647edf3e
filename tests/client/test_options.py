"""One settings object, checked once: every bad value is a clear error naming the setting."""

from __future__ import annotations

import math

import pytest

from rovlink.client import ClientOptions


@pytest.mark.parametrize("keepalive_s", [math.nan, math.inf, -1.0, 1e-9, 0.001, 1e10, True, "1"])
def test_a_keepalive_that_is_no_interval_is_refused(keepalive_s: object) -> None:
    # (Before, NaN and infinity were taken as "never" and 1e-9 s sent ~35,000 queries a second.)
    with pytest.raises(ValueError, match=r"keepalive must be seconds from 0\.01 to 3600, or 0 or"):
        ClientOptions(keepalive_s=keepalive_s)  # type: ignore[arg-type]


@pytest.mark.parametrize("keepalive_s", [None, 0, 0.0, 0.01, 1.0, 3600])
def test_a_keepalive_interval_or_never_is_taken(keepalive_s: float | None) -> None:
    assert ClientOptions(keepalive_s=keepalive_s).keepalive_s == keepalive_s
