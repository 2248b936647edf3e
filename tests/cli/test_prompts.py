"""The questions commands ask before they act: the end of the input (Ctrl-D) is a no."""

from __future__ import annotations

import pytest

from tests.cli.conftest import RunCli

_CALIBRATE_KNOWN_POINTS = ["--depth", "200", "--surface-raw", "20", "--depth-raw", "120"]


@pytest.mark.parametrize(
    ("argv", "no"),
    [
        pytest.param(["calibrate", "sim://", *_CALIBRATE_KNOWN_POINTS], b"n\n", id="calibrate"),
        pytest.param(["check", "sim://", "--motion", "--only", "motion-stop"], b"no\n", id="check"),
        pytest.param(["tune", "sim://"], b"no\n", id="tune"),
    ],
)
def test_the_end_of_the_input_at_a_confirmation_is_a_no(
    run_cli: RunCli, argv: list[str], no: bytes
) -> None:
    # Regression: an EOFError traceback.
    declined = run_cli(*argv, stdin=no, tty=True)
    ended = run_cli(*argv, stdin=b"", tty=True)
    assert "Traceback" not in ended.err
    assert ended.status == declined.status != 0
    assert ended.err == declined.err
    # The same words, the prompt's line ended before them.
    assert ended.out.split() == declined.out.split()
    assert ended.out.endswith(("] \n", "on: \n"))
    assert declined.err.endswith("not confirmed; nothing was sent\n")


@pytest.mark.parametrize(
    "argv",
    [["calibrate", "sim://", *_CALIBRATE_KNOWN_POINTS], ["tune", "sim://"]],
    ids=lambda argv: argv[0],
)
def test_a_no_at_a_confirmation_is_said_on_stderr_as_every_failure(
    run_cli: RunCli, argv: list[str]
) -> None:
    # calibrate ended with status 1 and said only "not sent", on stdout: stderr, where a failure
    # is said, had nothing, and tune and check say a no there.
    result = run_cli(*argv, stdin=b"n\n", tty=True)
    assert result.status == 1
    assert result.err.splitlines()[-1] == f"rovlink {argv[0]}: not confirmed; nothing was sent"
    assert "not sent" not in result.out


def test_the_tune_prompt_says_the_most_thrust_the_relay_sends(run_cli: RunCli) -> None:
    # The relay swings ±--relay-power around the hull's trim, which it finds as it runs: 45 %
    # down on the heavy simulated hull at 30 %. Before, the prompt said "at up to 30 %".
    result = run_cli("tune", "sim://", "--relay-power", "40", stdin=b"no\n", tty=True)
    prompt = " ".join(result.err.split())
    assert "at ±40 % around the thrust that holds the vehicle still" in prompt
    assert "up to 80 %, around 100 cm (limits 20–300 cm)" in prompt
    assert "at up to 40 %" not in prompt


@pytest.mark.parametrize("answers", [b"", b"\n"], ids=["at the surface", "at the depth"])
def test_the_end_of_the_input_while_calibrating_stops_there(
    run_cli: RunCli, answers: bytes
) -> None:
    # Regression: an EOFError traceback from the "press Enter" prompts.
    result = run_cli("calibrate", "sim://", "--depth", "200", stdin=answers, tty=True)
    assert "Traceback" not in result.err
    assert result.status == 1
    assert result.err == "rovlink calibrate: the input ended at the prompt: nothing was sent\n"
