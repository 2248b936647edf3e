"""The thruster mixer in isolation (P8, P11)."""

from __future__ import annotations

from rovlink.controller import DEFAULT_THRUSTERS, ThrusterMixer
from rovlink.controller.mixer import duty


def test_duty_rounds_half_away_from_zero_and_is_symmetric() -> None:
    assert [duty(f, 255) for f in (0.5, -0.5, 0.0, 1.0, -1.0)] == [128, -128, 0, 255, -255]
    assert all(duty(f / 1000, 255) == -duty(-f / 1000, 255) for f in range(1001))


def test_vertical_thrust_goes_to_every_vertical_thruster() -> None:
    mixer = ThrusterMixer(DEFAULT_THRUSTERS, 255)
    assert mixer.duties(100.0) == [0, 0, 0, 0, 255, 255]
    assert mixer.duties(-20.0) == [0, 0, 0, 0, -51, -51]


def test_horizontal_fractions_are_normalised_to_the_power() -> None:
    mixer = ThrusterMixer(DEFAULT_THRUSTERS, 255)
    mixer.set_horizontal(0, 100)
    assert [round(f, 9) for f in mixer.horizontal_fractions()] == [1, 1, 1, 1, 0, 0]
    mixer.set_horizontal(30, 60)
    fractions = mixer.horizontal_fractions()
    assert max(abs(f) for f in fractions) == 0.6
    assert mixer.thruster_count == 6


def test_changing_max_pwm_rescales_the_horizontal_duties() -> None:
    mixer = ThrusterMixer(DEFAULT_THRUSTERS, 255)
    mixer.set_horizontal(180, 100)
    mixer.max_pwm = 100
    assert mixer.duties(0.0)[:4] == [-100, -100, -100, -100]
