"""The state as last sent follows the controller's rules (P7, P9, P11) and says "as last sent"."""

from __future__ import annotations

import pytest

from rovlink.piloting import CommandedState, LockState
from rovlink.protocol import Command, VerticalMode
from rovlink.protocol.announcements import STOP_COMMAND, Announcement, AnnouncementKind


def _state(*commands: Command) -> CommandedState:
    state = CommandedState()
    for command in commands:
        state.apply(command)
    return state


def test_nothing_sent_is_unknown_and_says_so() -> None:
    state = CommandedState()
    assert state.lock is LockState.UNKNOWN
    assert "no start/stop sent" in state.lock_text()
    assert "no mvdirect sent" in state.mode_text()
    assert (state.short_lock_text(), state.short_mode_text()) == ("lock not sent", "mode not sent")


def test_start_unlocks_and_stop_locks_and_clears_set_points() -> None:
    state = _state(
        Command("start"), Command("mvdirect", (0,)), Command("mvd", (120,)), Command("th", (90, 40))
    )
    assert state.lock_text() == "unlocked (as last sent)"
    assert (state.target_depth_cm, state.direction_deg, state.power_percent) == (120, 90, 40)
    assert state.mode_text() == "depth (as last sent), target 120 cm"
    state.apply(Command("stop"))
    assert state.lock_text() == "locked (as last sent)"
    assert (state.target_depth_cm, state.direction_deg, state.power_percent) == (None, 0, 0)


@pytest.mark.parametrize(
    "command",
    [
        Command("mvd", (100,)),
        Command("th", (0, 50)),
        Command("mvs", (20,)),
        Command("h+"),
        Command("h-"),
    ],
)
def test_motion_while_locked_is_reported_as_dropped_and_changes_nothing(command: Command) -> None:
    state = _state(Command("stop"))
    before = CommandedState(**{name: getattr(state, name) for name in state.__slots__})
    warning = state.apply(command)
    assert warning is not None
    assert command.name in warning
    assert "locked (as last sent)" in warning
    # Nothing the controller holds changes; the command is still the last one sent.
    assert state.last_command == command
    assert state.last_dropped_because == warning
    state.last_command, state.last_dropped_because = before.last_command, None
    assert state == before


def test_mode_mismatch_is_reported_as_dropped() -> None:
    state = _state(Command("start"), Command("mvdirect", (1,)))
    warning = state.apply(Command("mvd", (100,)))
    assert warning is not None
    assert "mvdirect 0" in warning
    assert state.target_depth_cm is None
    assert state.apply(Command("mvs", (-30,))) is None
    assert state.mode_text() == "direct (as last sent), thrust -30 %"


def test_entering_depth_mode_while_unlocked_holds_the_entry_depth() -> None:
    state = _state(Command("start"), Command("mvdirect", (1,)), Command("mvdirect", (0,)))
    assert state.vertical_mode is VerticalMode.DEPTH
    assert state.holding_entry_depth
    assert "holding its depth on entry" in state.mode_text()
    state.apply(Command("mvd", (50,)))
    assert not state.holding_entry_depth


def test_start_while_unlocked_changes_nothing_as_the_controller_does() -> None:
    state = _state(Command("start"), Command("th", (270, 25)))
    state.apply(Command("start"))
    assert (state.direction_deg, state.power_percent) == (270, 25)


def test_th_360_is_0_and_settings_leave_the_state_alone() -> None:
    state = _state(
        Command("start"), Command("th", (360, 10)), Command("mgmp", (200,)), Command("qd")
    )
    assert state.direction_deg == 0
    assert state.horizontal_text() == "0° at 10 % (as last sent)"


_STOPPED = Announcement(AnnouncementKind.LOCKED, STOP_COMMAND)
_UNLOCKED = Announcement(AnnouncementKind.UNLOCKED)


def test_a_stop_heard_locks_as_the_tools_own_and_says_where_it_came_from() -> None:
    state = _state(Command("start"), Command("mvdirect", (1,)), Command("th", (90, 40)))
    assert state.hear(_STOPPED)
    assert state.lock is LockState.LOCKED
    assert (state.power_percent, state.direction_deg) == (0, 0)
    assert state.lock_text() == "locked (stopped by another line)"
    assert state.short_lock_text() == "locked (heard)"
    assert state.apply(Command("th", (0, 10))) is not None  # dropped: locked
    assert state.vertical_mode is VerticalMode.DIRECT  # a stop leaves the mode


def test_a_failsafe_heard_names_its_reason() -> None:
    state = _state(Command("start"))
    assert state.hear(Announcement(AnnouncementKind.LOCKED, "failsafe: no valid frame for 2 s"))
    assert (
        state.lock_text() == "locked (stopped by the controller: failsafe: no valid frame for 2 s)"
    )


def test_what_the_tool_sent_heard_back_changes_nothing() -> None:
    state = _state(Command("stop"))
    assert not state.hear(_STOPPED)
    assert state.lock_text() == "locked (as last sent)"
    state.apply(Command("start"))
    assert not state.hear(_UNLOCKED)
    assert not state.hear(Announcement(AnnouncementKind.ANOTHER_LINE_DRIVES, "<th.0.1>"))
    assert state.lock_text() == "unlocked (as last sent)"


def test_an_unlock_heard_is_shown_but_the_tool_stays_locked_until_it_unlocks() -> None:
    state = _state(Command("stop"))
    assert state.hear(_UNLOCKED)
    assert (state.lock, state.latest_lock) == (LockState.LOCKED, LockState.UNLOCKED)
    assert state.apply(Command("th", (0, 10))) is not None  # nothing relayed: still dropped
    state.apply(Command("start"))
    assert (state.heard_lock, state.lock_text()) == (None, "unlocked (as last sent)")


def test_a_suspected_reset_forgets_what_was_heard() -> None:
    state = _state(Command("start"))
    state.hear(_STOPPED)
    state.forget_after_reset()
    assert (state.heard_lock, state.lock) == (None, LockState.UNKNOWN)
    assert state.lock_text().startswith("unknown: after a suspected controller reset")


def test_the_lock_as_sent_stays_the_tools_own_for_leaving() -> None:
    # A tool that unlocked the robot stops it on leaving unless it locked it itself.
    state = _state(Command("start"))
    state.hear(_STOPPED)
    state.hear(_UNLOCKED)
    state.hear(_STOPPED)
    assert (state.lock, state.sent_lock) == (LockState.LOCKED, LockState.UNLOCKED)
    state.apply(Command("stop"))
    assert state.sent_lock is LockState.LOCKED
    assert _state(Command("stop")).sent_lock is LockState.LOCKED
