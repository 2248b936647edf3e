"""The Arduino sketch (``firmware/c/arduino/rovlink_controller``) on a host: its ESC pulses, claw
pins, replies and failsafes, against the protocol.

``arduino_host/`` stands in for the few Arduino core calls the sketch makes: a clock the test
advances (simulated milliseconds, no sleeping), digital and analog inputs the test sets, a serial
port. The sketch itself is compiled unchanged, with the protocol layer beside it. With
``--pty`` the same build serves the sketch on a pseudo-terminal in real time, for
``rovlink check``.
"""

from __future__ import annotations

import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from rovlink.client.links import open_link
from rovlink.client.url import parse_url
from rovlink.conformance import SuiteOptions, run_checks
from tests.firmware.c_build import (
    FIRMWARE,
    GCC,
    GXX,
    LAYER,
    STRICT,
    WARNINGS,
    build,
    run_script,
    send,
)

SKETCH = FIRMWARE / "arduino" / "rovlink_controller"
HOST = Path(__file__).resolve().parent / "arduino_host"
pytestmark = pytest.mark.skipif(
    GCC is None or GXX is None, reason="gcc and g++ are not installed (.ci/debian-packages)"
)

NEUTRAL_US = 1500
FULL_UP_US = 2000
LEAK_PIN = 2
PRESSURE_PIN = 14  # A0
#: The raw reading at 300 cm with the sketch's defaults (zero 20, k 200: 2 cm per count).
RAW_AT_300_CM = 170


@dataclass(frozen=True)
class Shown:
    """One ``show`` of the host build: the time, the six ESC pulses, the claw pins, output."""

    at_ms: int
    vertical_us: tuple[int, int]
    horizontal_us: tuple[int, int, int, int]
    claw: tuple[int, int]
    output: bytes


@pytest.fixture(scope="module")
def sketch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    build_dir = tmp_path_factory.mktemp("sketch")
    objects = []
    for source in LAYER:  # (C, compiled apart: the sketch's own files are C++)
        output = build_dir / source.with_suffix(".o").name
        command = [str(GCC), *STRICT, "-c", f"-I{FIRMWARE}", "-o", str(output), str(source)]
        subprocess.run(command, check=True, timeout=120)
        objects.append(output)
    flags = ("-std=c++11", *WARNINGS, "-Werror", f"-I{HOST}", f"-I{SKETCH}")
    sources = [HOST / "sketch_host.cpp", HOST / "pty_host.cpp", *objects]
    return build(build_dir / "sketch", sources, *flags, compiler=GXX)


def _run(sketch: Path, script: list[str], *power_on: str) -> list[Shown]:
    """Run ``script`` (see sketch_host.cpp) on a freshly powered-on sketch; every ``show``."""
    shown = []
    for words in run_script(sketch, script, *power_on):
        pulses = [int(word) for word in words[3:9]]
        shown.append(
            Shown(
                at_ms=int(words[1]),
                vertical_us=(pulses[0], pulses[1]),
                horizontal_us=(pulses[2], pulses[3], pulses[4], pulses[5]),
                claw=(int(words[10]), int(words[11])),
                output=bytes.fromhex(words[13]) if len(words) > 13 else b"",
            )
        )
    return shown


@pytest.mark.integration
def test_the_sketch_answers_a_query_and_drives_nothing_while_locked(sketch: Path) -> None:
    (shown,) = _run(sketch, ["run 20", send(b"#qd!#th.0.100!"), "run 20", "show"])
    assert shown.output == b"$qd.0!"
    assert shown.vertical_us + shown.horizontal_us == (NEUTRAL_US,) * 6


@pytest.mark.integration
def test_stop_puts_every_esc_at_neutral_at_once(sketch: Path) -> None:
    moving, stopped = _run(
        sketch,
        [
            "run 20",
            send(b"#start!#mvdirect.1!#mvs.+50!#th.0.100!#h+!"),
            "run 20",
            "show",
            send(b"#stop!"),
            "run 1",  # (loop() reads the byte; no tick is due in this millisecond)
            "show",
        ],
    )
    assert moving.vertical_us == (1750, 1750)
    assert moving.horizontal_us == (FULL_UP_US,) * 4
    assert stopped.vertical_us + stopped.horizontal_us == (NEUTRAL_US,) * 6
    assert stopped.claw == (0, 0)


@pytest.mark.integration
def test_link_loss_stops_and_locks_after_two_seconds(sketch: Path) -> None:
    before, after, refused = _run(
        sketch,
        [
            "run 20",
            send(b"#debug1!#start!#mvdirect.1!#mvs.+50!"),
            "run 1950",
            "show",
            "run 100",
            "show",
            send(b"#mvs.+50!"),
            "run 20",
            "show",
        ],
    )
    assert before.vertical_us == (1750, 1750)
    assert after.vertical_us == (NEUTRAL_US, NEUTRAL_US)
    assert b"failsafe: no valid frame for 2 s" in after.output
    assert refused.vertical_us == (NEUTRAL_US, NEUTRAL_US)
    assert b"motors are locked" in refused.output


@pytest.mark.integration
def test_the_claw_runs_for_one_pulse(sketch: Path) -> None:
    running, stopped = _run(
        # (the bytes take 1 ms to arrive at 115200 baud; the pulse ends at the tick after 50 ms)
        sketch,
        ["run 20", send(b"#start!#h-!"), "run 40", "show", "run 25", "show"],
    )
    assert running.claw == (0, 1)
    assert stopped.claw == (0, 0)


@pytest.mark.integration
def test_the_claw_reverses_without_both_bridge_inputs_high(sketch: Path) -> None:
    # Before: #h+! after #h-! set the open input HIGH while the close input was still HIGH; on
    # a bridge of discrete transistors that is a short across the supply (the host stand-in
    # exits with status 3 when it sees both HIGH). Each pulse turns the other input off first.
    closing, opening, closing_again = _run(
        sketch,
        [
            "run 20",
            send(b"#start!#h-!"),
            "run 10",
            "show",
            send(b"#h+!"),
            "run 10",
            "show",
            send(b"#h-!"),
            "run 10",
            "show",
        ],
    )
    assert closing.claw == (0, 1)
    assert opening.claw == (1, 0)
    assert closing_again.claw == (0, 1)


@pytest.mark.integration
def test_a_hung_loop_resets_the_board_instead_of_running_on(sketch: Path) -> None:
    # Before: a loop stuck in a call (an I2C read of an IMU that never ends, in on_reply) left
    # the ESCs on their last pulse, which the Servo library goes on sending from its interrupt,
    # and the link watchdog (P17), in the loop, never came. Now the chip's watchdog resets the
    # board, which starts locked, at neutral (P21).
    running, hung, after = _run(
        sketch,
        [
            "run 20",
            send(b"#start!#mvdirect.1!#mvs.+50!"),
            "run 20",
            "show",
            "hang 1000",
            "show",
            send(b"#mvs.+50!"),
            "run 20",
            "show",
        ],
    )
    assert running.vertical_us == (1750, 1750)
    assert hung.vertical_us == (NEUTRAL_US, NEUTRAL_US)
    assert hung.horizontal_us == (NEUTRAL_US,) * 4
    assert after.vertical_us == (NEUTRAL_US, NEUTRAL_US)  # (locked after the reset)


@pytest.mark.integration
def test_the_loop_keeps_the_watchdog_fed(sketch: Path) -> None:
    # Replies, debug lines and ticks never keep the loop from resetting the watchdog in time.
    (shown,) = _run(
        sketch,
        [
            "run 20",
            send(b"#debug1!#start!#mvdirect.1!#mvs.+50!" + b"#qsa!" * 40 + b"#x!" * 100),
            "run 1500",
            send(b"#qd!"),
            "run 20",
            "show",
        ],
    )
    assert shown.vertical_us == (1750, 1750)  # (no reset: still unlocked, still driving)


#: millis() wraps to 0 after this many ms (49.7 days): it is 32 bits on the boards.
_WRAP_MS = 2**32


def _days_later(at_ms: int) -> list[str]:
    """Script steps that bring the clock to ``at_ms`` as days of running would: in quarters,
    with the loop run after each (the sketch's times are told apart by differences, which a
    single jump of more than 2**31 ms would turn negative, as no real clock does)."""
    return [step for i in (1, 2, 3) for step in (f"clock {at_ms * i // 4}", "run 20")] + [
        f"clock {at_ms}"
    ]


@pytest.mark.integration
def test_the_claw_stops_after_one_pulse_begun_50_ms_before_the_clock_wraps(
    sketch: Path,
) -> None:
    # Before: the pulse's end was kept as a time, 0 meaning none; a pulse begun 50 ms before
    # millis() wraps ends at 0, and the claw ran until the next claw command or stop.
    running, stopped = _run(
        sketch,
        [
            *_days_later(_WRAP_MS - 60),
            send(b"#start!"),
            "run 10",
            send(b"#h+!"),  # (read at 2**32 - 50 ms)
            "run 40",
            "show",
            "run 30",
            "show",
        ],
    )
    assert running.claw == (1, 0)
    assert stopped.claw == (0, 0)


@pytest.mark.integration
def test_the_ticks_and_the_link_watchdog_go_on_across_the_clock_wrap(sketch: Path) -> None:
    # A 32-bit clock wrapping (49.7 days on): the depth ticks go on, a link kept alive stays
    # unlocked, and a link lost just before the wrap still stops the robot 2 s after.
    alive, lost = _run(
        sketch,
        [
            *_days_later(_WRAP_MS - 1000),
            send(b"#start!#mvdirect.1!#mvs.+50!"),
            *(step for _ in range(4) for step in ("run 500", send(b"#qd!"))),
            "show",
            "run 2100",
            "show",
        ],
    )
    assert alive.vertical_us == (1750, 1750)
    assert lost.vertical_us == (NEUTRAL_US, NEUTRAL_US)


@pytest.mark.integration
def test_a_leak_present_at_power_on_is_latched(sketch: Path) -> None:
    # Before: the latch was set only by a falling edge; a probe already wet at power-on never
    # made one, and the sketch answered $q.l.0! (P14).
    (shown,) = _run(sketch, ["run 20", send(b"#q.l!"), "run 5", "show"], f"{LEAK_PIN}=0")
    assert shown.output == b"$q.l.1!"


@pytest.mark.integration
def test_a_leak_still_present_after_slreset_is_latched_again(sketch: Path) -> None:
    # Before: #slreset! cleared the latch for good while the probe stayed wet (no new edge).
    (shown,) = _run(
        sketch,
        [
            f"pin {LEAK_PIN} 0",
            "run 20",
            send(b"#q.l!#slreset!"),
            "run 50",
            send(b"#q.l!"),
            "run 5",
            "show",
        ],
    )
    assert shown.output == b"$q.l.1!$q.l.1!"


@pytest.mark.integration
def test_a_short_leak_pulse_is_latched_until_slreset(sketch: Path) -> None:
    latched, reset = _run(
        sketch,
        [
            "run 20",
            f"pin {LEAK_PIN} 0",
            f"pin {LEAK_PIN} 1",  # (shorter than a tick: only the interrupt sees it)
            "run 50",
            send(b"#q.l!"),
            "run 5",
            "show",
            send(b"#slreset!#q.l!"),
            "run 20",
            send(b"#q.l!"),
            "run 5",
            "show",
        ],
    )
    assert latched.output == b"$q.l.1!"
    assert reset.output == b"$q.l.0!$q.l.0!"


@pytest.mark.integration
def test_a_depth_hold_at_rest_starts_without_a_kick(sketch: Path) -> None:
    # Before: the speed estimate took the depth of its last hold (0 cm at power-on) as the
    # depth a tick ago, so a hold begun at rest at 300 cm saw 30 000 cm/s of descent and
    # drove the vertical thrusters full up for seconds (P10: derivative on measurement).
    shown = _run(
        sketch,
        [
            f"analog {PRESSURE_PIN} {RAW_AT_300_CM}",
            "run 20",
            send(b"#qd!#start!#mvdirect.1!#mvdirect.0!"),
            "run 30",
            "show",
            "run 300",
            "show",
        ],
    )
    assert shown[0].output == b"$qd.300!"
    for moment in shown:
        assert moment.vertical_us == (NEUTRAL_US, NEUTRAL_US), moment


@pytest.mark.integration
def test_a_new_target_after_a_stop_starts_without_a_kick(sketch: Path) -> None:
    # Before: the speed estimate of an earlier hold survived #stop! and #start!.
    shown = _run(
        sketch,
        [
            "run 20",
            send(b"#start!#mvd.300!"),
            "run 500",
            f"analog {PRESSURE_PIN} {RAW_AT_300_CM}",  # (a 300 cm jump in one tick)
            "run 20",
            send(b"#stop!#start!#mvd.300!"),
            "run 30",
            "show",
        ],
    )
    assert shown[0].vertical_us == (NEUTRAL_US, NEUTRAL_US)


@pytest.mark.integration
@pytest.mark.slow
def test_rovlink_check_passes_against_the_sketch(sketch: Path) -> None:
    # Every check but the motion ones: the host build has no vehicle whose depth would change.
    process = subprocess.Popen(
        [str(sketch), "--pty"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        assert "sketch ready: pty " in line, line
        pty = line.split("pty ", 1)[1].strip()
        link = open_link(parse_url(pty))
        try:
            report = run_checks(link, pty, SuiteOptions())
        finally:
            link.close()
    finally:
        process.terminate()
        process.communicate(timeout=10)
    assert [(result.name, result.message) for result in report.failures] == []
    assert len(report.results) > 40


@pytest.mark.integration
def test_debug_output_never_holds_up_the_loop_on_an_uno(sketch: Path) -> None:
    # An Uno's core waits in Serial.write() for room in its 64-byte transmit buffer, which
    # drains at 11.5 bytes a ms: 200 '#' of line noise make 200 "dropped" lines, some 11 000
    # bytes, a second of waiting in which the claw would run on and no tick would come.
    running, later, answered = _run(
        sketch,
        [
            "run 20",
            send(b"#debug1!#start!#h-!"),
            "run 5",
            "show",
            send(b"#" * 200),
            "run 60",
            "show",
            send(b"#qd!"),
            "run 200",
            "show",
        ],
    )
    assert running.claw == (0, 1)
    assert later.at_ms <= running.at_ms + 60 + 10  # (a debug line waits for nothing)
    assert later.claw == (0, 0)  # the pulse ended on time
    assert b"$qd.0!" in answered.output  # a reply always goes out
    assert b"debug lines dropped: serial output busy" in later.output + answered.output


#: Four queries whose replies hold the loop up, spaces, then motion frames: on an Uno the 64-byte
#: receive buffer overflows meanwhile and a run of bytes is lost. (Each case: the spaces, the
#: frames.)
_OVERRUNS = (
    (37, (b"#th.0.34!", b"#th.90.17!", b"#th.0.15!", b"#th.0.81!", b"#th.180.35!", b"#th.90.78!")),
    (
        33,
        (b"#th.0.56!", b"#th.0.20!", b"#th.90.61!", b"#th.180.91!", b"#th.90.22!", b"#th.180.45!"),
    ),
    (
        33,
        (
            b"#th.90.48!",
            b"#th.270.90!",
            b"#th.90.67!",
            b"#th.180.73!",
            b"#th.0.84!",
            b"#th.180.91!",
        ),
    ),
)


def _horizontal_after(sketch: Path, stream: bytes) -> tuple[int, int, int, int]:
    (shown,) = _run(sketch, ["run 20", send(b"#start!"), "run 20", send(stream), "run 400", "show"])
    return shown.horizontal_us


@pytest.mark.integration
@pytest.mark.parametrize(("spaces", "frames"), _OVERRUNS, ids=("a", "b", "c"))
def test_bytes_lost_in_a_receive_overrun_never_splice_two_frames_into_a_third(
    sketch: Path, spaces: int, frames: tuple[bytes, ...]
) -> None:
    # Before: "#th.0.81!#th.180.35!#th.90.78!" less a run of lost bytes read as "#th.0.78!":
    # 78 % ahead, which nobody sent. Now the frame the lost bytes cut is dropped.
    after = _horizontal_after(sketch, b"#qsa!" * 4 + b" " * spaces + b"".join(frames))
    sent = {_horizontal_after(sketch, frame) for frame in frames}
    assert after in sent | {(NEUTRAL_US,) * 4}
