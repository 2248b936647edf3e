"""Options that take a command's value check it against the command table's range, not a
copy of it: a range changed in the table changes the option with it."""

from __future__ import annotations

import argparse

import pytest

from rovlink.cli import demo, tune
from rovlink.protocol import Argument, Kind, Spec


@pytest.fixture
def narrow_table(monkeypatch: pytest.MonkeyPatch) -> None:
    """A table whose mvd takes 0–50 cm and whose gains take 0–9."""
    depth = Spec("mvd", Kind.COMMAND, "depth", arguments=(Argument("target_depth_cm", 0, 50),))
    gain = Spec("mvpdp", Kind.COMMAND, "gain", arguments=(Argument("gain", 0, 9),))
    table = {"mvd": depth, "mvpdp": gain, "mvpdi": gain, "mvpidd": gain}
    for module in (demo, tune):
        monkeypatch.setattr(module, "lookup", table.__getitem__)


@pytest.mark.usefixtures("narrow_table")
def test_the_depth_options_take_mvd_s_range() -> None:
    for depth in (demo._depth_cm, tune._depth):
        assert depth("50") == 50
        with pytest.raises(argparse.ArgumentTypeError, match="51 is not in 0–50"):
            depth("51")


@pytest.mark.usefixtures("narrow_table")
def test_tune_s_restored_gains_take_the_gain_commands_range() -> None:
    assert tune._gains("9,0,9") == (9, 0, 9)
    with pytest.raises(argparse.ArgumentTypeError, match="three integers 0–9 as KP,KI,KD"):
        tune._gains("9,10,9")


def test_the_real_ranges() -> None:
    assert demo._depth_cm("9999") == 9999
    with pytest.raises(argparse.ArgumentTypeError, match="is not in 0–9999"):
        tune._depth("10000")
    assert tune._gains("99,0,99") == (99, 0, 99)
    with pytest.raises(argparse.ArgumentTypeError, match="three integers 0–99"):
        tune._gains("100,0,0")
