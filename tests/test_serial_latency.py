"""Both ends ask a serial device's driver for low latency when they open it: a USB adapter's
latency timer (16 ms on an FTDI chip) would otherwise hold every frame that long."""

from __future__ import annotations

import os
import tty
from collections.abc import Iterator

import pytest
import serial
from serial import serialposix

from rovlink.client.links import open_link
from rovlink.client.url import parse_url
from rovlink.controller.lines import SerialDeviceLine
from rovlink.serial_latency import ask_for_low_latency

pytestmark = pytest.mark.integration


@pytest.fixture
def pty_path() -> Iterator[str]:
    """The terminal side of a pseudo-terminal, free for a program to open."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    yield path
    os.close(master)


@pytest.fixture
def asked(monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """What pyserial's ports were asked for (a pseudo-terminal has no such mode to set)."""
    calls: list[bool] = []

    def record(port: serialposix.Serial, low_latency: bool) -> None:
        calls.append(low_latency)

    monkeypatch.setattr(serialposix.Serial, "set_low_latency_mode", record)
    return calls


def test_the_host_asks_for_low_latency_on_a_serial_device(pty_path: str, asked: list[bool]) -> None:
    link = open_link(parse_url(pty_path))
    try:
        assert asked == [True]
    finally:
        link.close()


def test_a_controller_asks_for_low_latency_on_its_serial_device(
    pty_path: str, asked: list[bool]
) -> None:
    line = SerialDeviceLine(pty_path, 115200)
    try:
        assert asked == [True]
    finally:
        line.close()


def test_a_port_without_the_mode_is_opened_all_the_same(pty_path: str) -> None:
    # A pseudo-terminal refuses the ioctl: the port stays as it was, and works.
    with serial.Serial(pty_path, 115200, timeout=0) as port:
        assert ask_for_low_latency(port, pty_path) is False
    link = open_link(parse_url(pty_path))
    try:
        link.write(b"#qd!")
    finally:
        link.close()


def test_a_port_object_without_the_method_is_left_alone() -> None:
    assert ask_for_low_latency(object(), "rfc2217://host:2217") is False
