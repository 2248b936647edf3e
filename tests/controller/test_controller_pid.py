"""The depth PID in isolation (P10)."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from rovlink.controller import DepthPid, DepthPidConfig

DT_S = 0.01


def _pid(kp: int = 0, ki: int = 0, kd: int = 0, **scales: float) -> DepthPid:
    return DepthPid(DepthPidConfig(kp=kp, ki=ki, kd=kd, **scales))


def test_proportional_term_is_gain_times_scale_times_error() -> None:
    pid = _pid(kp=20, kp_scale=0.1)
    assert pid.update(100, 110, DT_S) == 20.0  # 10 cm too deep: 20 % up


def test_integral_accumulates_error_over_time() -> None:
    pid = _pid(ki=10, ki_scale=0.01)
    for _ in range(100):  # one second, 10 cm too shallow
        output = pid.update(110, 100, DT_S)
    assert abs(output - (-1.0)) < 1e-9  # 0.1 %/(cm·s) × −10 cm × 1 s


def test_derivative_acts_on_measured_speed_with_a_filter() -> None:
    pid = _pid(kd=10, kd_scale=0.1, derivative_filter_s=0.0)
    pid.update(0, 100, DT_S)
    assert abs(pid.update(0, 101, DT_S) - 100.0) < 1e-9  # 100 cm/s × 1 %·s/cm
    filtered = _pid(kd=10, kd_scale=0.1, derivative_filter_s=0.5)
    filtered.update(0, 100, DT_S)
    assert 0 < filtered.update(0, 101, DT_S) < 5  # one count's step does not kick


def test_target_changes_do_not_kick_the_derivative() -> None:
    pid = _pid(kd=50)
    for target in (0, 500, 1000, 0):
        assert pid.update(target, 300, DT_S) == 0.0


@given(
    st.floats(-1e5, 1e5),
    st.floats(0, 9999),
    st.integers(0, 99),
    st.integers(0, 99),
    st.integers(0, 99),
)
def test_the_output_stays_within_the_limits(
    target: float, depth: float, kp: int, ki: int, kd: int
) -> None:
    pid = _pid(kp, ki, kd)
    for _ in range(3):
        assert -100.0 <= pid.update(target, depth, DT_S) <= 100.0
        assert 0.0 <= pid.update(target, depth, DT_S, lower=0.0) <= 100.0


def test_anti_windup_bounds_the_integral_during_saturation() -> None:
    pid = _pid(kp=10, ki=99, kd=0)
    for _ in range(100_000):  # 1000 s far too shallow
        pid.update(5000, 0, DT_S)
    assert pid.integral_percent >= -100.0
    # Without anti-windup the integral would be −1000 s × 5000 cm × 0.495 %/(cm·s); with it,
    # crossing the target reverses the output within a second.
    outputs = [pid.update(5000, 5200, DT_S) for _ in range(100)]
    assert outputs[-1] > 0


def test_reset_forgets_integral_and_speed() -> None:
    pid = _pid(ki=50, kd=50)
    for depth in range(100):
        pid.update(500, depth, DT_S)
    pid.reset()
    assert pid.integral_percent == 0.0
    assert pid.speed_cm_s == 0.0
    assert pid.update(500, 500, DT_S) == 0.0


def test_a_zero_time_step_does_not_integrate_or_divide_by_zero() -> None:
    pid = _pid(kp=0, ki=99, kd=99)
    pid.update(100, 0, DT_S)
    before = pid.integral_percent
    pid.update(100, 50, 0.0)
    assert pid.integral_percent == before
