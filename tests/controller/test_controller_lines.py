"""A controller served on several lines at once (a PTY and a TCP client): each line's bytes are
framed on their own; the checksum mode is the controller's, across lines."""

from __future__ import annotations

from tests.controller.controller_rig import Rig

PTY, TCP = "pty", "tcp"


def _send(rig: Rig, data: bytes, line: str) -> bytes:
    rig.controller.receive(data, line)
    return rig.controller.read_output()


def test_half_a_frame_on_one_line_survives_a_whole_frame_on_another(rig: Rig) -> None:
    # Before, one decoder took both lines' bytes: "#q" + "#qr!" + "d!" lost the first query.
    assert _send(rig, b"#q", PTY) == b""
    assert _send(rig, b"#qr!", TCP) == b"$qr.20!"
    assert _send(rig, b"d!", PTY) == b"$qd.0!"


def test_a_checksum_mode_set_on_one_line_holds_on_the_others(rig: Rig) -> None:
    assert _send(rig, b"#qd!", TCP) == b"$qd.0!"  # (the TCP line's decoder exists)
    assert _send(rig, b"#crcon!", PTY) == b""
    assert _send(rig, b"#qd!", TCP) == b""  # no checksum: dropped on every line
    assert _send(rig, b"#qd8C!", TCP) == b"$qd.0A2!"
    assert _send(rig, b"#crcoff!", TCP) == b""
    assert _send(rig, b"#qd!", PTY) == b"$qd.0!"


def test_a_line_opened_later_starts_in_the_controllers_checksum_mode(rig: Rig) -> None:
    assert _send(rig, b"#crcon!", PTY) == b""
    assert _send(rig, b"#qd8C!", TCP) == b"$qd.0A2!"


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
