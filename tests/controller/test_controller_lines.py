"""A controller served on several lines at once (a PTY and a TCP client): each line's bytes are
framed on their own and has its own checksum mode; the lock and the set-points are the
controller's, and every line hears when they change hands."""

from __future__ import annotations

from rovlink.controller import Controller, ControllerConfig
from rovlink.controller.hardware import Hardware
from tests.controller.controller_rig import Rig, make_rig

PTY, TCP = "pty", "tcp"


def _send(rig: Rig, data: bytes, line: str) -> bytes:
    rig.controller.receive(data, line)
    return rig.controller.read_output()


def test_half_a_frame_on_one_line_survives_a_whole_frame_on_another(rig: Rig) -> None:
    # Before, one decoder took both lines' bytes: "#q" + "#qr!" + "d!" lost the first query.
    assert _send(rig, b"#q", PTY) == b""
    assert _send(rig, b"#qr!", TCP) == b"$qr.20!"
    assert _send(rig, b"d!", PTY) == b"$qd.0!"


def test_a_checksum_mode_set_on_one_line_leaves_the_others_in_theirs(rig: Rig) -> None:
    # Before, the mode was the controller's: a program on the PTY that put it on made every
    # frame of a program on TCP a bad one (and each re-asserted its mode in turn, P21).
    assert _send(rig, b"#qd!", TCP) == b"$qd.0!"  # (the TCP line's decoder exists)
    assert _send(rig, b"#crcon!", PTY) == b""
    assert _send(rig, b"#qd!", TCP) == b"$qd.0!"  # plain on TCP, still
    assert _send(rig, b"#qd!", PTY) == b""  # no checksum on the PTY: dropped
    assert _send(rig, b"#qd8C!", PTY) == b"$qd.0A2!"
    assert rig.controller.state(PTY).checksum_enabled
    assert not rig.controller.state(TCP).checksum_enabled
    assert _send(rig, b"#crcoff!", TCP) == b""  # off where it was off: the PTY stays on
    assert _send(rig, b"#qd8C!", PTY) == b"$qd.0A2!"


def test_a_line_opened_later_starts_with_checksum_mode_off(rig: Rig) -> None:
    assert _send(rig, b"#crcon!", PTY) == b""
    assert _send(rig, b"#qd!", TCP) == b"$qd.0!"


def test_a_reset_puts_every_line_back_to_checksum_mode_off(rig: Rig) -> None:
    assert _send(rig, b"#crcon!", PTY) == b""
    rig.controller.reset()
    assert _send(rig, b"#qd!", PTY) == b"$qd.0!"


def test_after_a_reset_no_line_drives(rig: Rig) -> None:
    # A reset is power-on (P21): the first `#start!` after it takes over from nobody. Before,
    # the line that drove before the reset was still taken for the driver, and that start was
    # announced to every host as another line taking over the driving.
    assert _send(rig, b"#start!#th.0.20!", TCP) == b""
    rig.controller.reset()
    assert _send(rig, b"#debug1!", PTY) == b"debug: debug output on\r\n"
    assert _send(rig, b"#start!", PTY) == b"debug: motors unlocked\r\n"


def test_a_stop_on_one_line_stops_the_motion_another_line_commanded(rig: Rig) -> None:
    # Locking and set-points are the controller's, whatever the lines' checksum modes.
    assert _send(rig, b"#start!#th.0.100!", TCP) == b""
    assert _send(rig, b"#crcon!", PTY) == b""
    assert _send(rig, b"#stop!", PTY) == b""  # honoured bare in checksum mode (P3)
    state = rig.controller.state()
    assert state.locked
    assert state.power_percent == 0


def test_a_mode_frame_switches_its_own_line_per_frame(rig: Rig) -> None:
    # P3 on a line that read past its mode frame in the same chunk: the other line's switch
    # must not undo it.
    assert _send(rig, b"#qd!", PTY) == b"$qd.0!"
    assert _send(rig, b"#crcon!#crcoff!#qd!", TCP) == b"$qd.0!"
    assert _send(rig, b"#qd!", PTY) == b"$qd.0!"


def test_what_a_closed_line_left_of_a_frame_is_forgotten(rig: Rig) -> None:
    assert _send(rig, b"#mvd.1", TCP) == b""
    rig.controller.forget_line(TCP)
    assert _send(rig, b"00!#qd!", TCP) == b"$qd.0!"  # a new client's bytes, framed afresh
    assert rig.controller.state().target_depth_cm is None


def test_the_line_that_drove_going_stops_the_robot_at_once(rig: Rig) -> None:
    # Before, the robot drove on until the link-loss failsafe, or for good with it off.
    assert _send(rig, b"#start!#th.0.100!", TCP) == b""
    assert _send(rig, b"#debug1!", PTY) == b"debug: debug output on\r\n"
    rig.controller.forget_line(TCP)
    state = rig.controller.state()
    assert state.locked
    assert state.power_percent == 0
    assert rig.controller.read_output() == (
        b"debug: failsafe: the line that drove has gone: motors stopped and locked\r\n"
    )


def test_a_line_that_did_not_drive_going_stops_nothing(rig: Rig) -> None:
    assert _send(rig, b"#qd!", PTY) == b"$qd.0!"
    assert _send(rig, b"#start!#th.0.100!", TCP) == b""
    rig.controller.forget_line(PTY)
    assert not rig.controller.state().locked
    assert rig.controller.state().power_percent == 100


class _TwoWays:
    """A controller whose output is kept apart: for the line being read, for every line."""

    def __init__(self) -> None:
        rig = make_rig()
        hardware = Hardware(rig.thrusters, rig.pressure, rig.imu, rig.leak, rig.claw, rig.clock)
        self.own: list[bytes] = []
        self.every: list[bytes] = []
        self.controller = Controller(
            ControllerConfig(), hardware, self.own.append, write_to_every_line=self.every.append
        )

    def send(self, data: bytes, line: str) -> None:
        self.controller.receive(data, line)


def test_a_lock_change_from_one_line_is_told_to_every_line() -> None:
    # Before, a pilot's tool never heard that another tool's #stop! had locked the robot: the
    # line went back to the line that sent the stop only.
    two = _TwoWays()
    two.send(b"#debug1!", PTY)
    two.send(b"#start!#th.0.50!", TCP)
    two.send(b"#stop!", PTY)
    assert two.every == [
        b"debug: motors unlocked\r\n",
        b"debug: stop command: motors stopped and locked\r\n",
    ]
    assert b"".join(two.own).count(b"\r\n") == 2  # debug on; horizontal 0 deg at 50 %


def test_another_line_taking_over_the_driving_is_told_to_every_line() -> None:
    two = _TwoWays()
    two.send(b"#debug1!#start!#th.0.50!", TCP)
    two.send(b"#qsa!", PTY)  # polling: not driving
    two.send(b"#th.90.30!", TCP)  # the same line drives on
    assert two.every == [b"debug: motors unlocked\r\n"]
    two.send(b"#th.180.20!", PTY)
    assert two.every[1:] == [
        b"debug: <th.180.20> from another line: it drives now, and the link-loss failsafe "
        b"follows it\r\n"
    ]
