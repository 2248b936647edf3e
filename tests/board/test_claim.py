"""One controller per PWM board: the lock on its bus."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from rovlink.board.pi import board as pi_board
from rovlink.board.pi.board import PwmBoardInUseError, fake_bus_for, open_pi_board
from rovlink.board.pi.claim import BoardInUseError, claim_exclusively
from tests.board.rig import example_config


def test_a_lock_held_keeps_a_second_claim_out_until_released(tmp_path: Path) -> None:
    path = tmp_path / "i2c-1"
    path.touch()
    release = claim_exclusively(str(path))
    with pytest.raises(BoardInUseError, match="locked by another process"):
        claim_exclusively(str(path))
    release()
    claim_exclusively(str(path))()


def test_the_real_bus_is_locked_before_anything_is_written_to_it(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    config = example_config(i2c={"backend": "smbus2", "bus": 3}, imu={"sensor": "none"})
    bus = fake_bus_for(config)
    monkeypatch.setattr(pi_board, "Smbus2Bus", lambda number: bus)
    held = tmp_path / "held"
    held.touch()
    locked: list[tuple[str, int]] = []

    def claim(path: str) -> Callable[[], None]:
        locked.append((path, len(bus.snapshot())))
        return claim_exclusively(str(held))

    monkeypatch.setattr(pi_board, "claim_exclusively", claim)
    from gpiozero.pins.mock import MockFactory

    board = open_pi_board(config, pin_factory=MockFactory())
    try:
        assert locked == [("/dev/i2c-3", 0)]  # locked before the first transaction
        written = len(bus.snapshot())
        with pytest.raises(PwmBoardInUseError, match="on I²C bus 3 is in use by another rovlink"):
            open_pi_board(config, pin_factory=MockFactory())
        assert len(bus.snapshot()) == written
    finally:
        board.close()
    open_pi_board(config, pin_factory=MockFactory()).close()  # released with the board
