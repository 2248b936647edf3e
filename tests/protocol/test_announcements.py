"""The announcements a controller makes to every line (the lock, another line driving), as the
Python controller and the C reference print them and as the tools read them back."""

from __future__ import annotations

import pytest

from rovlink.controller import Controller, ControllerConfig
from rovlink.controller.hardware import Hardware
from rovlink.protocol import Decoder, Text
from rovlink.protocol.announcements import (
    STOP_COMMAND,
    UNLOCKED_TEXT,
    Announcement,
    AnnouncementKind,
    locked_text,
    read_announcement,
)
from tests.controller.controller_rig import make_rig
from tests.firmware.c_build import FIRMWARE


def _heard_on_every_line(*sends: tuple[bytes, str], ticks_s: float = 0.0) -> list[Announcement]:
    """What a tool on a third line reads, as announcements, of the controller's output."""
    rig = make_rig(watchdog_s=1.0)
    hardware = Hardware(rig.thrusters, rig.pressure, rig.imu, rig.leak, rig.claw, rig.clock)
    every: list[bytes] = []
    controller = Controller(
        ControllerConfig(watchdog_s=1.0),
        hardware,
        lambda _data: None,
        write_to_every_line=every.append,
    )
    for data, line in sends:
        controller.receive(data, line)
    while ticks_s > 0:
        rig.clock.time_s += 0.01
        controller.tick()
        ticks_s -= 0.01
    events = Decoder().feed(b"".join(every))
    texts = [event.text for event in events if isinstance(event, Text)]
    heard = [read_announcement(text) for text in texts]
    assert None not in heard, texts  # every line to every line is an announcement
    return [announcement for announcement in heard if announcement is not None]


def test_the_controllers_lock_changes_read_back_as_announcements() -> None:
    heard = _heard_on_every_line(
        (b"#debug1!", "pty"), (b"#start!#th.0.50!", "tcp"), (b"#stop!", "pty")
    )
    assert heard == [
        Announcement(AnnouncementKind.UNLOCKED),
        Announcement(AnnouncementKind.LOCKED, STOP_COMMAND),
    ]


def test_a_failsafe_and_a_take_over_read_back_with_their_detail() -> None:
    heard = _heard_on_every_line(
        (b"#debug1!#start!#th.0.50!", "tcp"), (b"#th.90.20!", "pty"), ticks_s=1.2
    )
    assert heard == [
        Announcement(AnnouncementKind.UNLOCKED),
        Announcement(AnnouncementKind.ANOTHER_LINE_DRIVES, "<th.90.20>"),
        Announcement(AnnouncementKind.LOCKED, "failsafe: no valid frame for 1 s"),
    ]


@pytest.mark.parametrize(
    "text",
    [
        "motors unlocked",  # not a debug line: another controller's words
        "debug: start: motors already unlocked, nothing changed",
        "debug: motors unlocked, or not",
        "debug: : motors stopped and locked",
        "debug: dropped <x: motors stopped and locked>: unknown command",
        "debug: ignored text between frames: 'motors unlocked'",
        "debug: vertical thrust +20 %",
        "",
        "\x00\xff debug: motors unlocked",
    ],
)
def test_other_text_is_no_announcement(text: str) -> None:
    assert read_announcement(text) is None


def test_the_c_reference_prints_the_same_words() -> None:
    # The tools recognise a board running the C reference as they do the Python controller.
    source = (FIRMWARE / "rovlink_proto.c").read_text()
    assert f'"{locked_text(STOP_COMMAND)}"' in source
    assert f'"{UNLOCKED_TEXT}"' in source
