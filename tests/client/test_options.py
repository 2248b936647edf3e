"""One settings object, checked once: every bad value is a clear error naming the setting."""

from __future__ import annotations

import math
from typing import Any

import pytest

import rovlink
import rovlink.aio
from rovlink.client import ClientOptions
from rovlink.controller import ControllerConfig


@pytest.mark.parametrize("keepalive_s", [math.nan, math.inf, -1.0, 1e-9, 0.001, 1e10])
def test_a_keepalive_that_is_no_interval_is_refused(keepalive_s: object) -> None:
    # (Before, NaN and infinity were taken as "never" and 1e-9 s sent ~35,000 queries a second.)
    with pytest.raises(ValueError, match=r"keepalive must be seconds from 0\.01 to 3600, or 0 or"):
        ClientOptions(keepalive_s=keepalive_s)  # type: ignore[arg-type]


#: A setting of the wrong type, and the start of its message: a TypeError, as docs/driver.md
#: says (and as a command method's wrong type is); it was a ValueError.
WRONG_TYPES = [
    ({"keepalive_s": True}, "keepalive must be seconds from"),
    ({"keepalive_s": "1"}, "keepalive must be seconds from"),
    ({"timeout_s": "0.5"}, "timeout must be a positive number of seconds"),
    ({"timeout_s": None}, "timeout must be a positive number of seconds"),
    ({"boot_timeout_s": "3"}, "boot_timeout must be a positive number of seconds"),
    ({"motion_timeout_s": True}, "motion_timeout must be a positive number of seconds"),
    ({"retries": 2.0}, "retries must be an integer from 0 to 100"),
    ({"retries": "2"}, "retries must be an integer from 0 to 100"),
]


@pytest.mark.parametrize(("setting", "message"), WRONG_TYPES)
def test_a_setting_of_the_wrong_type_is_a_type_error(setting: dict[str, Any], message: str) -> None:
    with pytest.raises(TypeError, match=message):
        ClientOptions(**setting)


@pytest.mark.parametrize(
    "setting", [{"timeout_s": 0}, {"timeout_s": math.nan}, {"retries": -1}, {"boot_timeout_s": 1e9}]
)
def test_a_setting_out_of_range_is_a_value_error(setting: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="must be"):
        ClientOptions(**setting)


@pytest.mark.parametrize("keepalive_s", [None, 0, 0.0, 0.01, 1.0, 3600])
def test_a_keepalive_interval_or_never_is_taken(keepalive_s: float | None) -> None:
    assert ClientOptions(keepalive_s=keepalive_s).keepalive_s == keepalive_s


@pytest.mark.parametrize("connect", [rovlink.connect, rovlink.aio.connect])
def test_a_setting_given_beside_options_is_refused_not_dropped(connect: Any) -> None:
    # (Before, connect(url, options=..., timeout=0.1) ran with the options' timeout, silently.)
    options = ClientOptions(retries=0)
    with pytest.raises(
        TypeError,
        match=r"timeout=0\.1, reconnect=True given with options=: .*"
        r"\(timeout_s=0\.1, reconnect=True\)",
    ):
        connect("sim://", options=options, timeout=0.1, reconnect=True)
    with pytest.raises(TypeError, match=r"options must be a rovlink\.client\.ClientOptions"):
        connect("sim://", options={"timeout_s": 0.1})


def test_options_alone_or_with_keywords_at_their_defaults_are_taken() -> None:
    options = ClientOptions(timeout_s=0.3, keepalive_s=None)
    with rovlink.connect("sim://", options=options, timeout=0.5, keepalive=1.0) as rov:
        assert rov._options is options


async def _an_async_callback(event: object) -> None:
    """What a program on the asyncio client may pass as a callback, and never hear from."""


@pytest.mark.parametrize("name", ["on_event", "on_stray"])
@pytest.mark.parametrize("connect", [rovlink.connect, rovlink.aio.connect])
def test_an_async_def_callback_is_refused_before_connecting(connect: Any, name: str) -> None:
    # (Before, it was taken: each event made a coroutine that nothing awaited, a RuntimeWarning,
    # and the program heard nothing.)
    with pytest.raises(TypeError, match=rf"{name} must be a plain function, not an async def"):
        connect("sim://", **{name: _an_async_callback})


def test_the_default_keepalive_feeds_the_default_link_loss_failsafe() -> None:
    # P17: an idle host keeps an unlocked robot alive with a query; by default the controller
    # stops after 2 s without a valid frame, so the keep-alive comes well inside that.
    keepalive_s = ClientOptions().keepalive_s
    watchdog_s = ControllerConfig().watchdog_s
    assert watchdog_s == 2.0
    assert keepalive_s is not None
    assert 0 < keepalive_s <= watchdog_s / 2
