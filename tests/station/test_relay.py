"""The relay's rules with a simulated clock: dead-man, staleness, renewal, cuts, depth nudges."""

from __future__ import annotations

import pytest

from rovlink.piloting import CommandedState
from rovlink.protocol import Command
from rovlink.station.relay import (
    LOCKED_STATUS,
    MIN_MOTION_INTERVAL_S,
    RENEW_S,
    STALE_INPUT_S,
    UNKNOWN_LOCK_STATUS,
    PilotInput,
    ThrustRelay,
)


class Wire:
    """The relay with the state as last sent kept as the tracked client keeps it."""

    def __init__(self) -> None:
        self.state = CommandedState()
        self.relay = ThrustRelay(self.state)
        self.sent: list[str] = []

    def send(self, commands: list[Command]) -> list[str]:
        for command in commands:
            self.state.apply(command)
        texts = [str(command) for command in commands]
        self.sent += texts
        return texts

    def update(self, pilot: PilotInput, now_s: float, depth_cm: int | None = None) -> list[str]:
        return self.send(self.relay.update(pilot, now_s, depth_cm=depth_cm))

    def check(self, now_s: float) -> list[str]:
        return self.send(self.relay.check(now_s))

    def armed_and_flying(self, direction_deg: int = 90, power_percent: int = 50) -> None:
        self.send([Command("start")])
        assert self.update(PilotInput(False, pad_timestamp_ms=0.0), 0.0) == []
        assert self.update(PilotInput(True, direction_deg, power_percent, 0, 1.0), 0.01) == [
            f"#th.{direction_deg}.{power_percent}!"
        ]


RELEASED = PilotInput(False, pad_timestamp_ms=0.0)


def test_nothing_moves_until_the_dead_man_was_seen_released():
    wire = Wire()
    wire.send([Command("start")])
    assert wire.update(PilotInput(True, 90, 50, 0, 1.0), 0.0) == []
    assert wire.relay.status == "release the dead-man to arm"
    assert wire.update(RELEASED, 0.05) == []
    assert wire.update(PilotInput(True, 90, 50, 0, 2.0), 0.1) == ["#th.90.50!"]


def test_only_changes_go_on_the_wire():
    wire = Wire()
    wire.armed_and_flying()
    assert wire.update(PilotInput(True, 90, 50, 0, 2.0), 0.05) == []
    assert wire.update(PilotInput(True, 95, 50, 0, 3.0), 0.1) == ["#th.95.50!"]
    assert wire.update(PilotInput(True, 95, 0, 0, 4.0), 0.15) == ["#th.95.0!"]


def test_a_heading_of_360_is_the_heading_of_0():
    # (Before, 360 never equalled the 0 sent for it: every input sent #th.0.40! again.)
    wire = Wire()
    wire.armed_and_flying(direction_deg=0, power_percent=40)
    assert wire.update(PilotInput(True, 360, 40, 0, 2.0), 0.05) == []
    assert wire.update(PilotInput(True, 360, 40, 0, 3.0), 0.1) == []
    assert wire.update(PilotInput(True, 360, 60, 0, 4.0), 0.15) == ["#th.0.60!"]


def test_releasing_the_dead_man_zeroes_at_once():
    wire = Wire()
    wire.armed_and_flying()
    assert wire.update(PilotInput(False, 90, 50, 0, 2.0), 0.05) == ["#th.90.0!"]
    assert wire.relay.armed  # pressing it again flies
    assert wire.update(PilotInput(True, 90, 50, 0, 3.0), 0.1) == ["#th.90.50!"]


def test_a_silent_page_is_cut_after_the_staleness_limit():
    wire = Wire()
    wire.armed_and_flying()
    assert wire.check(0.01 + STALE_INPUT_S) == []
    assert wire.check(0.02 + STALE_INPUT_S) == ["#th.90.0!", "#mvs.+0!"]
    assert "no input from the page" in wire.relay.status
    assert wire.check(1.0) == []  # once
    # Input again with the dead-man still held does not resume: it must be released first.
    assert wire.update(PilotInput(True, 90, 50, 0, 9.0), 1.1) == []


def test_a_frozen_pad_is_cut_even_while_the_page_sends():
    wire = Wire()
    wire.armed_and_flying()
    for step in range(1, 6):  # the same pad timestamp, 50 ms apart, for 250 ms: still fresh
        now_s = 0.01 + step * 0.05
        assert wire.update(PilotInput(True, 90, 50, 0, 1.0), now_s) == []
        assert wire.check(now_s + 0.001) == []
    now_s = 0.01 + STALE_INPUT_S + 0.05
    assert wire.update(PilotInput(True, 90, 50, 0, 1.0), now_s)[0] == "#th.90.0!"
    assert "gamepad reported nothing" in wire.relay.status


def test_a_held_motion_is_renewed_for_the_drivers_motion_timeout():
    wire = Wire()
    wire.armed_and_flying()
    renewals = [
        wire.update(PilotInput(True, 90, 50, 0, float(step)), 0.01 + step * 0.05)
        for step in range(2, 25)
    ]
    sent = [texts for texts in renewals if texts]
    assert sent
    assert all(texts == ["#th.90.50!"] for texts in sent)
    assert len(sent) == pytest.approx(1.15 / RENEW_S, abs=1)


def test_a_cut_sends_zero_even_if_the_state_says_zero_and_disarms():
    wire = Wire()
    wire.send([Command("start"), Command("mvdirect", (1,))])
    assert wire.send(wire.relay.cut("the pilot left")) == ["#th.0.0!", "#mvs.+0!"]
    assert not wire.relay.armed


def test_a_cut_sends_no_mvs_in_depth_mode_as_last_sent():
    wire = Wire()
    wire.send([Command("start"), Command("mvdirect", (0,))])
    assert wire.send(wire.relay.cut("the pilot left")) == ["#th.0.0!"]


def test_a_cut_with_no_mode_sent_yet_zeroes_vertical_thrust_too():
    # Another program may have left the controller in direct mode with vertical thrust; in
    # depth mode it drops the mvs, harmlessly.
    wire = Wire()
    wire.send([Command("start")])
    assert wire.send(wire.relay.cut("the pilot left")) == ["#th.0.0!", "#mvs.+0!"]


def test_direct_mode_relays_vertical_thrust_and_zeroes_it():
    wire = Wire()
    wire.send([Command("start"), Command("mvdirect", (1,))])
    wire.update(RELEASED, 0.0)
    assert wire.update(PilotInput(True, 0, 0, 40, 1.0), 0.05) == ["#mvs.+40!"]
    assert wire.update(PilotInput(False, 0, 0, 40, 2.0), 0.1) == ["#mvs.+0!"]


def test_depth_mode_nudges_the_target_from_the_depth_read():
    wire = Wire()
    wire.send([Command("start")])
    wire.update(RELEASED, 0.0)
    sent: list[str] = []
    now_s = 0.0
    for step in range(1, 22):  # full down for about a second
        now_s = step * 0.05
        sent += wire.update(PilotInput(True, 0, 0, -100, float(step)), now_s, depth_cm=100)
    assert sent[0].startswith("#mvd.10")
    assert wire.state.target_depth_cm == pytest.approx(130, abs=2)


def test_locked_as_last_sent_relays_nothing_and_says_so():
    wire = Wire()
    wire.send([Command("stop")])
    wire.update(RELEASED, 0.0)
    assert wire.relay.status == LOCKED_STATUS
    assert wire.update(PilotInput(True, 90, 50, 0, 1.0), 0.05) == []
    # (Before, the stick held after STOP read "flying", in green, beside "motors: locked".)
    assert wire.relay.status == LOCKED_STATUS
    wire.send([Command("start")])
    assert wire.update(PilotInput(True, 90, 50, 0, 2.0), 0.1) == ["#th.90.50!"]
    assert wire.relay.status == "flying"


def test_flying_with_the_lock_unknown_says_that_the_motors_may_be_locked():
    wire = Wire()  # nothing sent yet: a controller after a reset is locked
    wire.update(RELEASED, 0.0)
    assert wire.update(PilotInput(True, 90, 50, 0, 1.0), 0.05) == ["#th.90.50!"]
    assert wire.relay.status == UNKNOWN_LOCK_STATUS


@pytest.mark.parametrize(
    ("field", "value"), [("direction_deg", 361), ("power_percent", -1), ("vertical_percent", 101)]
)
def test_input_out_of_the_command_tables_range_is_refused(field, value):
    with pytest.raises(ValueError, match=field):
        PilotInput(True, **{field: value})


def test_changes_closer_than_the_interval_are_held_and_the_latest_wins():
    wire = Wire()
    wire.armed_and_flying()  # #th.90.50! at 0.01
    assert wire.update(PilotInput(True, 92, 50, 0, 2.0), 0.015) == []
    assert wire.update(PilotInput(True, 94, 50, 0, 3.0), 0.02) == []
    assert wire.relay.due_s == pytest.approx(0.01 + MIN_MOTION_INTERVAL_S)
    assert wire.send(wire.relay.flush(0.025)) == []  # not yet
    assert wire.send(wire.relay.flush(0.031)) == ["#th.94.50!"]
    assert wire.relay.due_s is None


def test_zero_thrust_is_never_held_back():
    wire = Wire()
    wire.armed_and_flying()
    assert wire.update(PilotInput(True, 90, 0, 0, 2.0), 0.012) == ["#th.90.0!"]
    wire.armed_and_flying()
    assert wire.update(PilotInput(False, 90, 50, 0, 2.0), 0.012) == ["#th.90.0!"]
    assert wire.relay.due_s is None


def test_a_held_change_is_dropped_when_the_input_goes_stale_or_is_released():
    wire = Wire()
    wire.armed_and_flying()
    assert wire.update(PilotInput(True, 92, 50, 0, 2.0), 0.015) == []
    assert wire.update(PilotInput(False, 92, 50, 0, 3.0), 0.016) == ["#th.90.0!"]
    assert wire.send(wire.relay.flush(1.0)) == []
    wire.update(PilotInput(True, 90, 50, 0, 4.0), 0.02)
    assert wire.update(PilotInput(True, 96, 50, 0, 5.0), 0.025) == []
    assert wire.check(0.026 + STALE_INPUT_S) == ["#th.90.0!", "#mvs.+0!"]
    assert wire.send(wire.relay.flush(1.0)) == []


def test_the_watchdog_round_also_sends_what_is_due():
    wire = Wire()
    wire.armed_and_flying()
    assert wire.update(PilotInput(True, 92, 50, 0, 2.0), 0.015) == []
    assert wire.check(0.05) == ["#th.92.50!"]
