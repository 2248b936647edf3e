"""Thrusters and claw as pulses on a PCA9685: the ESC and servo side of the board."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rovlink.board.pi.pca9685 import Pca9685
from rovlink.logs import get_logger

__all__ = ["EscChannel", "EscThrusters", "MotorClaw", "ServoClaw", "pulse_for_duty"]

logger = get_logger(__name__)

_MAX_DUTY = 255


@dataclass(frozen=True, slots=True)
class EscChannel:
    """One ESC: its PCA9685 channel, direction and pulse range, µs."""

    channel: int
    reversed: bool = False
    min_us: float = 1100.0
    neutral_us: float = 1500.0
    max_us: float = 1900.0


def pulse_for_duty(esc: EscChannel, duty: int) -> float:
    """The pulse for a signed duty −255…+255: linear from neutral to the end of the range.

    >>> esc = EscChannel(0)
    >>> pulse_for_duty(esc, 0), pulse_for_duty(esc, 255), pulse_for_duty(esc, -255)
    (1500.0, 1900.0, 1100.0)
    >>> pulse_for_duty(EscChannel(0, reversed=True), 51)
    1420.0
    """
    if esc.reversed:
        duty = -duty
    duty = max(-_MAX_DUTY, min(_MAX_DUTY, duty))
    if duty >= 0:
        return esc.neutral_us + (esc.max_us - esc.neutral_us) * duty / _MAX_DUTY
    return esc.neutral_us + (esc.neutral_us - esc.min_us) * duty / _MAX_DUTY


def _write_retried_once(pca: Pca9685, pulses: dict[int, float]) -> None:
    """Write ``pulses``; a failed write is tried once more with each of them written again (a
    glitch on a bus next to thruster cables is not a reason to stop); a second failure is
    raised, and the board loop then ends with the outputs at neutral."""
    try:
        pca.set_pulses_us(pulses)
    except OSError as error:
        logger.warning("PCA9685 write failed (%s); writing the outputs again", error)
        pca.forget_written()
        pca.set_pulses_us(pulses)


class EscThrusters:
    """The controller's thruster outputs (layout order) as ESC pulses on one or more PCA9685
    (several chips on one bus for more than 16 outputs)."""

    def __init__(self, chips: Sequence[Pca9685], escs: Sequence[tuple[Pca9685, EscChannel]]):
        """``chips``: every PWM board, in the order they are started; ``escs``: each thruster's
        chip and ESC, in layout order."""
        self._chips = tuple(chips)
        self._escs = tuple(escs)
        if any(pca not in self._chips for pca, _ in self._escs):
            raise ValueError("an ESC is on a PCA9685 that is not among the chips")

    @property
    def chips(self) -> tuple[Pca9685, ...]:
        """Every PWM board, in the order they are started."""
        return self._chips

    def neutral_pulses_us(self) -> dict[Pca9685, dict[int, float]]:
        """Every ESC's neutral pulse, by chip (every chip, those without an ESC too) and
        channel."""
        pulses: dict[Pca9685, dict[int, float]] = {pca: {} for pca in self._chips}
        for pca, esc in self._escs:
            pulses[pca][esc.channel] = esc.neutral_us
        return pulses

    def set_duties(self, duties: Sequence[int]) -> None:
        """Apply signed duties, one per thruster of the layout: one write per chip of the
        outputs changed on it (a failed write is retried once; every chip is written before
        a failure is raised)."""
        if len(duties) != len(self._escs):
            raise ValueError(f"{len(duties)} duties for {len(self._escs)} thrusters")
        pulses: dict[Pca9685, dict[int, float]] = {pca: {} for pca in self._chips}
        for (pca, esc), duty in zip(self._escs, duties, strict=True):
            pulses[pca][esc.channel] = pulse_for_duty(esc, duty)
        _on_every_chip(pulses, _write_retried_once)

    def neutral(self) -> None:
        """Neutral on every ESC, written even if the driver believes it is there already
        (every chip is written before a failure is raised)."""

        def write_again(pca: Pca9685, pulses: dict[int, float]) -> None:
            pca.forget_written()
            pca.set_pulses_us(pulses)

        _on_every_chip(self.neutral_pulses_us(), write_again)


def _on_every_chip(
    pulses: dict[Pca9685, dict[int, float]],
    write: Callable[[Pca9685, dict[int, float]], None],
) -> None:
    """``write`` each chip's ``pulses``, every chip even after one failed (a chip that does not
    answer must not leave the thrusters of another running); then raise the first failure."""
    failures: list[Exception] = []
    for pca, chip_pulses in pulses.items():
        if not chip_pulses:
            continue
        try:
            write(pca, chip_pulses)
        except (OSError, RuntimeError) as error:  # (RuntimeError: a chip never started)
            if len(pulses) > 1:
                logger.error("PCA9685 at %#04x: pulses not set: %s", pca.address, error)
            failures.append(error)
    if failures:
        raise failures[0]


class MotorClaw:
    """A claw driven by a motor behind an ESC or motor driver: a pulse each way, neutral stops."""

    def __init__(
        self, pca: Pca9685, channel: int, *, open_us: float, close_us: float, neutral_us: float
    ) -> None:
        self._pca = pca
        self.channel = channel
        self._pulses = {1: open_us, -1: close_us, 0: neutral_us}

    @property
    def pca(self) -> Pca9685:
        """The PWM board the claw is on."""
        return self._pca

    def rest_pulse_us(self) -> float:
        """The pulse at start and after a stop: the motor stands still."""
        return self._pulses[0]

    def drive(self, direction: int) -> None:
        """+1 opens, −1 closes, 0 stops; a failed write is retried once, as the thrusters'."""
        _write_retried_once(self._pca, {self.channel: self._pulses[direction]})

    def neutral(self) -> None:
        """Stop the motor."""
        self.drive(0)


class ServoClaw:
    """A claw on a positional servo: each ``h+``/``h-`` pulse moves it a step; it holds between.

    The controller runs the claw for a fixed pulse (P16), which suits a motor; for a servo the
    pulse becomes one step of ``step_us`` toward open or closed, and the servo holds its place.
    """

    def __init__(
        self,
        pca: Pca9685,
        channel: int,
        *,
        open_us: float,
        close_us: float,
        start_us: float,
        step_us: float,
    ) -> None:
        self._pca = pca
        self.channel = channel
        self._low_us, self._high_us = sorted((open_us, close_us))
        self._open_sign = 1 if open_us >= close_us else -1
        self._step_us = step_us
        self.position_us = start_us

    @property
    def pca(self) -> Pca9685:
        """The PWM board the claw is on."""
        return self._pca

    def rest_pulse_us(self) -> float:
        """The pulse at start: the configured start position."""
        return self.position_us

    def drive(self, direction: int) -> None:
        """+1 steps toward open, −1 toward closed, 0 holds."""
        if direction == 0:
            return
        target = self.position_us + direction * self._open_sign * self._step_us
        self.position_us = min(self._high_us, max(self._low_us, target))
        _write_retried_once(self._pca, {self.channel: self.position_us})

    def neutral(self) -> None:
        """A servo has no thrust to stop: it holds where it is."""
