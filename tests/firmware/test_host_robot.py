"""The C reference's host robot (``firmware/c/host/host_robot.c``) stepped in simulated time:
its vertical output on stop, link loss and a depth hold, tick by tick, with no sleeping.

``host_robot_steps.c`` compiles the host robot without its main and its pseudo-terminal, and
runs it from a script (see its header).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from rovlink.protocol.announcements import (
    STOP_COMMAND,
    Announcement,
    AnnouncementKind,
    read_announcement,
)
from tests.firmware.c_build import LAYER, STRICT, build, needs_gcc, run_script, send

STEPS = Path(__file__).resolve().parent / "host_robot_steps.c"
pytestmark = [pytest.mark.integration, needs_gcc]


@dataclass(frozen=True)
class Shown:
    """One ``show``: simulated time, the vertical output of the last tick, depth, lock, output."""

    at_ms: int
    thrust_percent: float
    depth_cm: int
    locked: bool
    output: bytes


@pytest.fixture(scope="module")
def steps(tmp_path_factory: pytest.TempPathFactory) -> Path:
    binary = tmp_path_factory.mktemp("steps") / "host-robot-steps"
    return build(binary, [STEPS, *LAYER], *STRICT, "-O1")


def _run(steps: Path, script: list[str]) -> list[Shown]:
    shown = []
    for words in run_script(steps, script):
        shown.append(
            Shown(
                at_ms=int(words[1]),
                thrust_percent=float(words[3]),
                depth_cm=int(words[5]),
                locked=words[7] == "1",
                output=bytes.fromhex(words[9]) if len(words) > 9 else b"",
            )
        )
    return shown


def test_stop_zeroes_the_vertical_output_at_the_next_tick(steps: Path) -> None:
    moving, stopped = _run(
        steps,
        [
            send(b"#start!#mvdirect.1!#mvs.-60!"),
            "run 100",
            "show",
            send(b"#stop!"),
            "run 10",
            "show",
        ],
    )
    assert moving.thrust_percent == -60.0
    assert stopped.thrust_percent == 0.0
    assert stopped.locked


def test_link_loss_stops_and_locks_after_two_seconds(steps: Path) -> None:
    alive, lost = _run(
        steps,
        [
            send(b"#debug1!#start!#mvdirect.1!#mvs.+40!"),
            "run 2000",
            "show",
            "run 20",
            "show",
        ],
    )
    assert alive.thrust_percent == 40.0
    assert not alive.locked
    assert lost.thrust_percent == 0.0
    assert lost.locked
    assert b"failsafe: no valid frame for 2 s" in lost.output


def test_a_hold_after_a_stop_starts_without_the_speed_of_the_earlier_hold(steps: Path) -> None:
    # Before: the speed estimate of a dive stopped while descending (about 1 m/s) survived
    # #stop! and #start!: the new hold, begun 5 s later with the robot rising on its buoyancy,
    # drove the vertical thrusters full up for 100 ms and shot some 20 cm above its depth (P10:
    # derivative on measurement, no kick).
    shown = _run(
        steps,
        [
            send(b"#start!#mvd.300!"),
            "run 1000",
            send(b"#stop!"),
            "run 5000",
            "show",
            send(b"#start!#mvdirect.1!#mvdirect.0!"),
            "run 10",
            "show",
            "run 40",
            "show",
            "run 50",
            "show",
            "run 400",
            "show",
        ],
    )
    held_at_cm = shown[0].depth_cm
    assert held_at_cm > 50  # (the dive went down before the stop)
    for moment in shown[1:4]:
        assert moment.thrust_percent < 20.0, moment
    assert shown[4].depth_cm > held_at_cm - 10, shown[4]


def test_a_leak_pulse_is_latched_until_slreset_and_not_after(steps: Path) -> None:
    # Before: --leak-at wetted the probe for good, so the latch came back after every
    # #slreset!, where rovlink sim --leak-at gives a 100 ms pulse: the same bytes got $q.l.1!
    # from one simulated controller and $q.l.0! from the other.
    latched, reset = _run(
        steps,
        [
            "leak-at 300",
            "run 500",
            send(b"#q.l!"),
            "show",
            send(b"#slreset!"),
            "run 100",
            send(b"#q.l!"),
            "show",
        ],
    )
    assert latched.output == b"$q.l.1!"
    assert reset.output == b"$q.l.0!"


def test_slreset_while_the_probe_is_still_wet_latches_again(steps: Path) -> None:
    (shown,) = _run(
        steps, ["leak-at 300", "run 350", send(b"#slreset!"), "run 20", send(b"#q.l!"), "show"]
    )
    assert shown.output == b"$q.l.1!"


def test_attitude_ties_round_up_as_the_python_controller_does(tmp_path: Path) -> None:
    """A value exactly half-way between two degrees goes up, toward +∞, as in rovlink's
    controller (docs/hardware.md): −2.5° → −2 and −0.5° → 0, not away from zero."""
    probe = tmp_path / "attitude_probe.c"
    probe.write_text(
        "#define RL_HOST_ROBOT_NO_MAIN\n"
        '#include "host/host_robot.c"\n'
        "int main(void) {\n"
        "    const double values[] = {-90.6, -2.5, -0.5, -0.4, 0.5, 2.5, 89.5, 90.5};\n"
        "    size_t i;\n"
        "    for (i = 0; i < sizeof values / sizeof values[0]; i++)\n"
        '        printf("%d\\n", attitude_deg(values[i]));\n'
        "    return 0;\n"
        "}\n"
    )
    binary = build(
        tmp_path / "attitude-probe", [probe, *LAYER], *STRICT, "-Wno-unused-function", "-O1"
    )
    printed = [int(word) for (word,) in run_script(binary, [])]
    assert printed == [-90, -2, 0, 0, 1, 3, 90, 90]


def test_its_lock_announcements_are_the_ones_rovlink_tools_hear(steps: Path) -> None:
    # The C reference spells the controller's announcements out (C cannot take them from
    # rovlink.protocol.announcements): a tool with --hear-other-lines hears its lock change.
    shown = _run(
        steps,
        [
            send(b"#debug1!#start!"),
            "run 10",
            "show",
            send(b"#stop!"),
            "run 10",
            "show",
            send(b"#start!"),
            "run 2100",
            "show",
        ],
    )
    lines = b"".join(each.output for each in shown).decode("ascii").splitlines()
    heard = [read_announcement(line) for line in lines]
    assert [each for each in heard if each is not None] == [
        Announcement(AnnouncementKind.UNLOCKED),
        Announcement(AnnouncementKind.LOCKED, STOP_COMMAND),
        Announcement(AnnouncementKind.UNLOCKED),
        Announcement(AnnouncementKind.LOCKED, "failsafe: no valid frame for 2 s"),
    ]
