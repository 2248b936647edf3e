"""``rovlink tune`` on the command line."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from rovlink.cli import main
from rovlink.cli.tune import parse_triple


def test_list_rules_and_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tune", "sim://", "--list-rules"]) == 0
    assert "heave-poles" in capsys.readouterr().out
    assert main(["tune", "sim://", "--rule", "magic", "--yes"]) == 2
    assert "unknown rule 'magic'" in capsys.readouterr().err
    assert main(["tune", "sim://", "--depth", "500", "--max-depth", "300", "--yes"]) == 2
    assert "must lie between the limits" in capsys.readouterr().err
    assert main(["tune", "sim://", "--min-depth", "300", "--max-depth", "200", "--yes"]) == 2
    assert "0 ≤ min < max" in capsys.readouterr().err


def test_parse_triple() -> None:
    assert parse_triple("0.05,0.005,0.1") == (0.05, 0.005, 0.1)
    with pytest.raises(argparse.ArgumentTypeError, match="three numbers"):
        parse_triple("1,2")


def test_motors_need_yes_without_a_terminal(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    assert main(["tune", "sim://"]) == 2
    assert "--yes is needed" in capsys.readouterr().err


@pytest.mark.integration
@pytest.mark.slow
def test_relay_on_the_light_vehicle_in_real_time(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plot = tmp_path / "tune.png"
    status = main(
        ["tune", "sim://?preset=light&seed=2", "--yes", "--no-verify", "--plot", str(plot)]
    )
    out = capsys.readouterr().out
    assert status == 0
    assert "ultimate gain Ku" in out
    assert "sent back mvpdp 40, mvpdi 30, mvpidd 20" in out
    assert plot.stat().st_size > 10_000
