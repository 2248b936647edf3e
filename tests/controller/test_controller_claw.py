"""P16: claw pulses."""

from __future__ import annotations

from tests.controller.controller_rig import TICK_S, Rig, make_rig


def test_h_plus_opens_for_one_pulse(armed_rig: Rig) -> None:
    armed_rig.send(b"#h+!")
    assert armed_rig.claw.direction == 1  # at once, not at the next tick
    armed_rig.run(0.04)
    assert armed_rig.claw.direction == 1
    armed_rig.run(0.01)
    assert armed_rig.claw.direction == 0
    start, stop = armed_rig.claw.history[-2][0], armed_rig.claw.history[-1][0]
    assert 0.05 <= stop - start <= 0.05 + TICK_S


def test_h_minus_closes(armed_rig: Rig) -> None:
    armed_rig.send(b"#h-!")
    assert armed_rig.claw.direction == -1
    armed_rig.run(0.1)
    assert armed_rig.claw.direction == 0


def test_a_new_pulse_restarts_the_timer_in_the_new_direction(armed_rig: Rig) -> None:
    armed_rig.send(b"#h+!")
    armed_rig.run(0.03)
    armed_rig.send(b"#h-!")
    assert armed_rig.claw.direction == -1
    armed_rig.run(0.04)
    assert armed_rig.claw.direction == -1  # 70 ms after the first pulse, 40 into the second
    armed_rig.run(0.01)
    assert armed_rig.claw.direction == 0


def test_the_pulse_length_is_configurable() -> None:
    rig = make_rig(claw_pulse_ms=200, watchdog_s=0.0)
    rig.send(b"#start!#h+!")
    rig.run(0.19)
    assert rig.claw.direction == 1
    rig.run(0.01)
    assert rig.claw.direction == 0


def test_stop_idles_the_claw_at_once(armed_rig: Rig) -> None:
    armed_rig.send(b"#h+!#stop!")
    assert armed_rig.claw.direction == 0
    assert armed_rig.controller.state().claw_direction == 0


def test_a_new_pulse_in_the_same_direction_restarts_the_timer(armed_rig: Rig) -> None:
    armed_rig.send(b"#h+!")
    armed_rig.run(0.03)
    armed_rig.send(b"#h+!")
    armed_rig.run(0.04)
    assert armed_rig.claw.direction == 1  # 70 ms after the first pulse, 40 into the second
    armed_rig.run(0.01)
    assert armed_rig.claw.direction == 0


def test_the_link_loss_failsafe_idles_a_running_claw() -> None:
    # P17 acts as on #stop!, which leaves the claw idle (P7).
    rig = make_rig(watchdog_s=0.02, claw_pulse_ms=1000)
    rig.send(b"#start!#h-!")
    rig.run(0.05)
    assert rig.controller.locked
    assert rig.claw.direction == 0
