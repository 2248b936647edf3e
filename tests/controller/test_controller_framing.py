"""P1 through the controller: frame limits, resynchronisation, bytes between frames."""

from __future__ import annotations

from tests.controller.controller_rig import Rig


def _padded_mvd(total_bytes: int, target_cm: int = 100) -> bytes:
    """``#mvd.000…100!`` with leading zeros up to ``total_bytes`` bytes in all."""
    digits = str(target_cm)
    zeros = total_bytes - len("#mvd.!") - len(digits)
    return b"#mvd." + b"0" * zeros + digits.encode() + b"!"


def test_a_frame_of_64_bytes_is_executed_one_of_65_is_not(armed_rig: Rig) -> None:
    frame = _padded_mvd(64, 100)
    assert len(frame) == 64
    armed_rig.send(frame)
    assert armed_rig.controller.state().target_depth_cm == 100
    frame = _padded_mvd(65, 200)
    assert len(frame) == 65
    armed_rig.send(frame)
    assert armed_rig.controller.state().target_depth_cm == 100


def test_a_start_character_inside_a_frame_starts_a_new_one(rig: Rig) -> None:
    assert rig.send(b"#mvd.1#qd!") == b"$qd.0!"
    assert rig.send(b"#mgmp.1$qd.1!#qr!") == b"$qr.20!"


def test_a_non_printable_byte_discards_the_frame(armed_rig: Rig) -> None:
    armed_rig.send(b"#mvd.1\r00!#mvd.1 00!#mvd.1\x0000!")
    assert armed_rig.controller.state().target_depth_cm is None


def test_bytes_between_frames_are_skipped(rig: Rig) -> None:
    assert rig.send(b"hello \r\n\x00\xff #qd! \r\n junk #qr!\r\n") == b"$qd.0!$qr.20!"


def test_many_frames_in_one_chunk_are_executed_in_order(armed_rig: Rig) -> None:
    output = armed_rig.send(b"#mvd.100!#qd!#mvd.200!#mgmp.9!#qr!")
    assert output == b"$qd.0!$qr.20!"
    state = armed_rig.controller.state()
    assert (state.target_depth_cm, state.max_pwm) == (200, 9)
