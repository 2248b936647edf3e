"""Every driver method, checked against the command table, validated before anything is sent."""

from __future__ import annotations

import inspect
import re

import pytest

from rovlink.aio import AsyncClient
from rovlink.client import Client, InvalidArgumentError
from rovlink.client import operations as ops
from rovlink.client.method_table import METHODS
from rovlink.protocol import COMMANDS, Command

METHOD_NAMES = sorted([method.name for method in METHODS] + ["send", "send_raw"])


def test_the_methods_cover_every_command_of_the_table() -> None:
    sent = {frame for method in METHODS for frame in method.frames}
    assert sent == {spec.name for spec in COMMANDS}


@pytest.mark.parametrize("method", METHOD_NAMES)
def test_both_clients_have_every_method_with_the_same_signature(method: str) -> None:
    blocking = getattr(Client, method)
    asynchronous = getattr(AsyncClient, method)
    assert not inspect.iscoroutinefunction(blocking)
    assert inspect.iscoroutinefunction(asynchronous)
    assert inspect.signature(blocking) == inspect.signature(asynchronous).replace(
        return_annotation=inspect.signature(blocking).return_annotation
    )
    for function in (blocking, asynchronous):
        assert "Example::" in (function.__doc__ or ""), f"{function.__qualname__}: no example"


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: ops.move(361, 10), "move: direction_deg must be in 0–360 (#th), got 361"),
        (lambda: ops.move(90, -1), "move: power_percent must be in 0–100 (#th), got -1"),
        (
            lambda: ops.move(90, 12.5),  # type: ignore[arg-type]
            "move: power_percent must be a whole number in 0–100 (#th), got 12.5",
        ),
        (lambda: ops.max_pwm(256), "set_max_pwm: duty must be in 0–255 (#mgmp), got 256"),
        (
            lambda: ops.vertical_thrust(101),
            "set_vertical_thrust: percent must be in -100…+100 (#mvs), got 101",
        ),
        (lambda: ops.hold_depth(10000), "hold_depth: depth_cm must be in 0–9999 (#mvd)"),
        (lambda: ops.depth_zero(1025), "set_depth_zero: raw must be in 0–1024 (#sdz)"),
        (lambda: ops.depth_scale(-1), "set_depth_scale: k must be in 0–10000 (#sdk)"),
        (lambda: ops.depth_pid(p=10, d=100), "set_depth_pid: d must be in 0–99 (#mvpidd)"),
        (ops.depth_pid, "give at least one of p, i, d"),
        (lambda: ops.raw_frame(""), "frame must not be empty"),
        (lambda: ops.raw_frame("#qd°!"), "ASCII"),
    ],
)
def test_out_of_range_values_name_the_argument_and_range(call: object, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        call()  # type: ignore[operator]


def test_invalid_argument_error_carries_the_details() -> None:
    with pytest.raises(InvalidArgumentError) as caught:
        ops.move(90, 101)
    error = caught.value
    assert (error.method, error.argument, error.value, error.range_text) == (
        "move",
        "power_percent",
        101,
        "0–100",
    )


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: ops.move(True, 10), "move: direction_deg must be an integer, got True"),
        (
            lambda: ops.move("90", 10),  # type: ignore[arg-type]
            "move: direction_deg must be an integer, got '90'",
        ),
        (
            lambda: ops.checksum(1),  # type: ignore[arg-type]
            "set_checksum: enabled must be True or False, got 1",
        ),
        (
            lambda: ops.direct_mode("yes"),  # type: ignore[arg-type]
            "set_direct_mode: enabled must be True or False",
        ),
    ],
)
def test_wrong_types_are_type_errors(call: object, message: str) -> None:
    with pytest.raises(TypeError, match=message):
        call()  # type: ignore[operator]


def test_whole_floats_and_integer_likes_are_accepted() -> None:
    assert str(ops.move(90.0, 50)) == "#th.90.50!"  # type: ignore[arg-type]
    assert [str(c) for c in ops.depth_pid(i=0)] == ["#mvpdi.0!"]


def test_a_value_in_range_but_not_whole_is_told_so() -> None:
    # (Before: "direction_deg must be in 0–360 (#th), got 1.5", which 1.5 is.)
    with pytest.raises(InvalidArgumentError, match=r"must be a whole number in 0–360 \(#th\)"):
        ops.move(1.5, 10)  # type: ignore[arg-type]
    assert ops.move(90.0, 10) == Command("th", (90, 10))  # type: ignore[arg-type]
