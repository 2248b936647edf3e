"""P2, P3: checksum mode, both directions, exact-match crcon/crcoff, the bare #stop! exception."""

from __future__ import annotations

from rovlink.protocol import Response, encode
from rovlink.protocol.checksum import get_algorithm
from tests.controller.controller_rig import Rig, make_rig


def _with_crc(body: bytes, algorithm: str = "crc8") -> bytes:
    return b"#" + body + get_algorithm(algorithm).digits(body) + b"!"


def test_checksum_mode_is_off_after_reset(rig: Rig) -> None:
    assert not rig.controller.state().checksum_enabled
    assert rig.send(b"#qd!") == b"$qd.0!"


def test_crcon_turns_checksums_on_in_both_directions(rig: Rig) -> None:
    assert rig.send(b"#crcon!") == b""
    assert rig.controller.state().checksum_enabled
    assert rig.send(b"#qd8C!") == encode(Response("qd", (0,)), "crc8")
    assert rig.send(b"#qd8C!") == b"$qd.0A2!"  # CRC-8/SMBUS of "qd.0"


def test_in_checksum_mode_a_frame_without_or_with_a_wrong_checksum_is_dropped(rig: Rig) -> None:
    rig.send(b"#crcon!")
    before = rig.controller.state()
    assert rig.send(b"#qd!") == b""
    assert rig.send(b"#qd8D!") == b""
    assert rig.send(b"#mgmp.100!") == b""
    assert rig.controller.state() == before


def test_receivers_accept_lowercase_hex(rig: Rig) -> None:
    rig.send(b"#crcon!")
    rig.send(_with_crc(b"start"))
    rig.send(b"#mvd.1004b!")  # PROTOCOL.md Part 3: mvd.100 → 4B
    assert rig.controller.state().target_depth_cm == 100


def test_bare_stop_is_honoured_in_checksum_mode(rig: Rig) -> None:
    rig.send(b"#crcon!")
    rig.send(_with_crc(b"start"))
    assert not rig.controller.locked
    rig.send(b"#stop!")
    assert rig.controller.locked


def test_checksummed_stop_is_honoured_too(rig: Rig) -> None:
    rig.send(b"#crcon!" + _with_crc(b"start"))
    rig.send(b"#stopA5!")
    assert rig.controller.locked


def test_crcoff_is_recognised_by_exact_match_in_checksum_mode(rig: Rig) -> None:
    # "crcoff" ends in the valid hex "ff": it must not be read as "crco" + checksum.
    rig.send(b"#crcon!#crcoff!")
    assert not rig.controller.state().checksum_enabled
    assert rig.send(b"#qd!") == b"$qd.0!"


def test_crcon_twice_and_crcoff_when_off_are_harmless(rig: Rig) -> None:
    rig.send(b"#crcon!#crcon!")
    assert rig.controller.state().checksum_enabled
    rig.send(b"#crcoff!#crcoff!")
    assert not rig.controller.state().checksum_enabled


def test_crcon_with_a_checksum_is_not_crcon(debug_rig: Rig) -> None:
    output = debug_rig.send(_with_crc(b"crcon"))
    assert not debug_rig.controller.state().checksum_enabled
    assert b"unknown" in output


def test_with_checksum_off_a_checksummed_frame_is_an_unknown_command(debug_rig: Rig) -> None:
    output = debug_rig.send(b"#qd8C!")
    assert output.startswith(b"debug: dropped <qd8C>: unknown")
    assert b"$" not in output


def test_every_reply_of_qsa_carries_its_own_checksum(rig: Rig) -> None:
    rig.send(b"#crcon!")
    output = rig.send(_with_crc(b"qsa"))
    frames = output.split(b"!")[:-1]
    assert len(frames) == 6
    algorithm = get_algorithm("crc8")
    for frame in frames:
        body, digits = frame[1:-2], frame[-2:]
        assert algorithm.verify(body, digits), frame


def test_the_algorithm_is_a_controller_setting() -> None:
    rig = make_rig(checksum_algorithm="xor")
    rig.send(b"#crcon!")
    assert rig.send(_with_crc(b"qd", "crc8")) == b""  # 8C is not the xor of "qd"
    assert rig.send(_with_crc(b"qd", "xor")) == encode(Response("qd", (0,)), "xor")


def test_reset_turns_checksum_mode_off(rig: Rig) -> None:
    rig.send(b"#crcon!")
    rig.controller.reset()
    assert rig.send(b"#qd!") == b"$qd.0!"
