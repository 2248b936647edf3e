"""Two-point depth calibration: the arithmetic, the checks, a simulated sensor, the command."""

from __future__ import annotations

import statistics

import pytest

from rovlink.cli import main
from rovlink.client import Client, ClientOptions
from rovlink.client.links import PortLink
from rovlink.sim.port import open_port
from rovlink.tuning.calibration import CalibrationError, two_point


def test_two_point_arithmetic() -> None:
    calibration = two_point(20.4, 95.0, 150)
    assert calibration.zero_raw == 20
    assert calibration.k == round(150 * 100 / (95.0 - 20))
    assert calibration.depth_for(95.0) == pytest.approx(150, abs=1)
    assert calibration.depth_for(0) == 0  # clamped, as P13 says


@pytest.mark.parametrize("surface_raw", [20.0, 20.3, 20.5, 20.6, 20.9])
@pytest.mark.parametrize(("counts", "depth_cm"), [(50.0, 100), (99.6, 200), (74.6, 150)])
def test_the_calibration_reads_the_known_depth_at_its_reading(
    surface_raw: float, counts: float, depth_cm: int
) -> None:
    # The zero the controller gets is whole: k is taken over the counts from it, so that only
    # k's own rounding (half a hundredth of a cm per count) stands between the known depth and
    # what the calibration gives there. Before, k came from the counts from the surface reading
    # itself: 20.6 and 120.6 for 200 cm gave zero 21 and k 200, 199.2 cm at the known depth.
    calibration = two_point(surface_raw, surface_raw + counts, depth_cm)
    counts_from_zero = surface_raw + counts - calibration.zero_raw
    given_cm = counts_from_zero * calibration.k / 100
    assert abs(given_cm - depth_cm) <= counts_from_zero * 0.5 / 100 + 1e-9


@pytest.mark.parametrize(
    ("surface", "depth_raw", "depth_cm", "message"),
    [
        (20, 25, 100, "5 counts apart"),
        (120, 20, 100, "-100 counts apart"),
        (20, 1100, 100, "outside the sensor's range"),
        (20, 31, 9999, "outside sdk's range"),
        (20, 80, 0, "must be > 0 cm"),
        (0, 1000, 2, "k would round to 0"),  # (sdk 0: every depth would read 0)
    ],
)
def test_two_point_refuses_what_cannot_calibrate(
    surface: float, depth_raw: float, depth_cm: int, message: str
) -> None:
    with pytest.raises(CalibrationError, match=message):
        two_point(surface, depth_raw, depth_cm)


def test_calibration_from_a_simulated_sensor_gives_its_true_scale() -> None:
    port = open_port(seed=5, manual=True, timeout=0.05)
    options = ClientOptions(keepalive_s=None, motion_timeout_s=None, boot_timeout_s=None)
    client = Client(PortLink(port, "sim"), options)
    try:
        port.robot.set_net_buoyancy(0.0)  # the vehicle stays where it is put

        def mean_raw_at(depth_m: float) -> float:
            port.vehicle.depth_m = depth_m
            port.vehicle.heave_m_s = 0.0
            readings = []
            for _ in range(40):
                port.advance(0.05)
                readings.append(client.pressure_raw())
            return statistics.fmean(readings)

        calibration = two_point(mean_raw_at(0.0), mean_raw_at(1.5), 150)
        sensors = port.robot.config.sensors
        assert calibration.zero_raw == round(sensors.pressure_zero_raw)
        assert calibration.k == pytest.approx(100 * 100 / sensors.pressure_counts_per_m, abs=3)
        client.set_depth_zero(calibration.zero_raw)
        client.set_depth_scale(calibration.k)
        assert client.depth_cm() == pytest.approx(150, abs=4)
    finally:
        client.close()


def test_cli_dry_run_shows_and_sends_nothing(capsys: pytest.CaptureFixture[str]) -> None:
    status = main(
        [
            "calibrate",
            "sim://",
            "--surface-raw",
            "20",
            "--depth-raw",
            "120",
            "--depth",
            "200",
            "--dry-run",
        ]
    )
    out = capsys.readouterr().out
    assert status == 0
    assert "sdz 20, sdk 200" in out
    assert "nothing sent" in out


def test_cli_sends_and_reports_errors_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    status = main(
        [
            "calibrate",
            "sim://?seed=1",
            "--surface-raw",
            "20",
            "--depth-raw",
            "70",
            "--depth",
            "100",
            "--yes",
        ]
    )
    assert status == 0
    assert "sent #sdz.20! #sdk.200!" in capsys.readouterr().out
    status = main(
        [
            "calibrate",
            "sim://",
            "--surface-raw",
            "20",
            "--depth-raw",
            "22",
            "--depth",
            "100",
            "--dry-run",
        ]
    )
    err = capsys.readouterr().err
    assert status == 1
    assert err.count("\n") == 1
    assert "2 counts apart" in err


def test_cli_measuring_without_a_terminal_is_a_usage_error(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    assert main(["calibrate", "sim://", "--depth", "100"]) == 2
    assert "give --surface-raw and --depth-raw" in capsys.readouterr().err
