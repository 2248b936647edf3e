"""``rovlink calibrate`` on a link that fails: one line saying what failed and what was sent."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from rovlink.client import ConnectionLostError
from tests.cli.conftest import RunCli
from tests.client.conftest import CONDITION_TIMEOUT_S, NO_REPLY_TIMEOUT_S, wait_until
from tests.client.fake_controller import FakeControllerServer

#: No readiness probe (the fake answers at once) and no retries: the script's one dropped
#: reply is a query that times out.
_LINK = ("--boot-timeout", "0", "--retries", "0", "--timeout", str(NO_REPLY_TIMEOUT_S))
_KNOWN_POINTS = ("--depth", "100", "--surface-raw", "20", "--depth-raw", "120")


@pytest.fixture
def deaf_controller() -> Iterator[FakeControllerServer]:
    """A controller that takes every command and leaves its first query unanswered."""
    served = FakeControllerServer(script=["drop"])
    yield served
    served.close()


def _calibration_sent(server: FakeControllerServer) -> list[str]:
    """The #sdz and #sdk frames the controller got, once the command has closed its connection
    (so every frame it sent has arrived)."""
    assert wait_until(lambda: len(server.fakes) == 1)
    assert server.ended[0].wait(CONDITION_TIMEOUT_S)
    return [frame for frame in server.fakes[0].frames() if frame.startswith(("#sdz", "#sdk"))]


@pytest.mark.integration
def test_a_depth_read_back_that_times_out_says_both_values_were_sent(
    run_cli: RunCli, deaf_controller: FakeControllerServer
) -> None:
    # Regression: a QueryTimeoutError traceback, after #sdz and #sdk had gone.
    result = run_cli("calibrate", deaf_controller.url, *_KNOWN_POINTS, "--yes", *_LINK)
    assert result.status == 1
    assert "Traceback" not in result.err
    assert result.err.splitlines()[-1] == (
        "rovlink calibrate: sent #sdz.20! #sdk.100!, but reading the depth back failed: "
        f"#qsa! got no valid reply within {NO_REPLY_TIMEOUT_S:g} s (1 attempt: timeout) on "
        f"tcp {deaf_controller.url.removeprefix('socket://')}"
    )
    assert _calibration_sent(deaf_controller) == ["#sdz.20!", "#sdk.100!"]


@pytest.mark.integration
def test_values_the_controller_did_not_take_are_an_error(run_cli: RunCli) -> None:
    # A controller that drops #sdz and #sdk (a reset, a firmware bug) and reads 123 cm at raw
    # 530, where sdz 20 sdk 100 give 510 cm. Before, calibrate said "sent ...; depth now
    # 123 cm" with status 0: nothing acknowledges a setting (P4), so nothing was compared.
    server = FakeControllerServer()
    try:
        result = run_cli("calibrate", server.url, *_KNOWN_POINTS, "--yes", *_LINK)
    finally:
        server.close()
    assert result.status == 1
    assert result.err.splitlines()[-1] == (
        "rovlink calibrate: sent #sdz.20! #sdk.100!, but the controller did not take them: it "
        "reads 123 cm at raw 530, where they give 510 cm (P13); did it reset, or drop the "
        "frames? calibrate again"
    )


@pytest.mark.integration
def test_a_measurement_that_times_out_sends_nothing(
    run_cli: RunCli, deaf_controller: FakeControllerServer
) -> None:
    # Regression: a QueryTimeoutError traceback from _mean_raw.
    result = run_cli(
        "calibrate",
        deaf_controller.url,
        "--depth",
        "100",
        "--samples",
        "1",
        *_LINK,
        stdin=b"\n",
        tty=True,
    )
    assert result.status == 1
    assert "Traceback" not in result.err
    assert result.err.splitlines()[-1] == (
        "rovlink calibrate: measuring the surface: #qr! got no valid reply within "
        f"{NO_REPLY_TIMEOUT_S:g} s (1 attempt: timeout) on "
        f"tcp {deaf_controller.url.removeprefix('socket://')}; nothing was sent"
    )
    assert _calibration_sent(deaf_controller) == []


@pytest.mark.integration
def test_a_link_lost_between_the_two_values_says_which_one_went(
    run_cli: RunCli, deaf_controller: FakeControllerServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The controller is left half calibrated: the user must know it.
    def lose_the_link(self: object, k: int) -> None:
        raise ConnectionLostError("the link to the controller was lost")

    monkeypatch.setattr("rovlink.client.Client.set_depth_scale", lose_the_link)
    result = run_cli("calibrate", deaf_controller.url, *_KNOWN_POINTS, "--yes", *_LINK)
    assert result.status == 1
    assert "Traceback" not in result.err
    assert result.err.splitlines()[-1] == (
        "rovlink calibrate: sent #sdz.20! but not #sdk.100!: the link to the controller was "
        "lost; the depth zero is new and its scale old: calibrate again"
    )
    assert _calibration_sent(deaf_controller) == ["#sdz.20!"]


@pytest.mark.integration
@pytest.mark.parametrize("at", ["set_depth_scale", "sensors"])
def test_an_interrupt_after_the_zero_went_says_what_was_sent(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch, at: str
) -> None:
    # Ctrl-C (or SIGTERM, taken as it) as #sdk goes, or as the depth is read back. Before,
    # only "interrupted": nothing said that the controller was left half calibrated, or that
    # both values had gone unchecked.
    def interrupted(self: object, *args: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(f"rovlink.client.Client.{at}", interrupted)
    server = FakeControllerServer()
    try:
        result = run_cli("calibrate", server.url, *_KNOWN_POINTS, "--yes", *_LINK)
        sent = _calibration_sent(server)
    finally:
        server.close()
    assert result.status == 130
    said = result.err.splitlines()
    assert said[-1] == "rovlink calibrate: interrupted"
    if at == "sensors":
        assert said[-2] == "sent #sdz.20! #sdk.100!; the depth was not read back"
        assert sent == ["#sdz.20!", "#sdk.100!"]
    else:
        assert said[-2] == (
            "sent #sdz.20!, interrupted while #sdk.100! was sent: the depth zero is new and "
            "its scale may be old: calibrate again"
        )
        assert sent == ["#sdz.20!"]


def test_given_readings_too_close_are_refused_before_the_port_opens(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, the port was opened first (a board that resets when it opens, reset for nothing;
    # a --record file left holding the connection's probe) and the readings refused after.
    from rovlink.cli import link_options

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("connected")

    monkeypatch.setattr(link_options, "connect", refuse)
    result = run_cli(
        "calibrate", "sim://", "--depth", "200", "--surface-raw", "20", "--depth-raw", "22", "--yes"
    )
    assert result.status == 1
    assert result.err == (
        "rovlink calibrate: the readings are 2 counts apart (surface 20, at 200 cm 22); at least "
        "10 are needed: go deeper, or check that the sensor reads more with depth\n"
    )


@pytest.mark.integration
def test_sending_without_a_terminal_to_ask_on_needs_yes(run_cli: RunCli) -> None:
    # As `tune` and `check --motion` refuse to act unasked. Before, calibrate asked only on a
    # terminal and, without one, sent #sdz and #sdk unasked (`calibrate … < /dev/null`).
    server = FakeControllerServer()
    try:
        result = run_cli("calibrate", server.url, *_KNOWN_POINTS, *_LINK)
    finally:
        server.close()
    assert result.status == 2
    assert result.err.splitlines()[-1] == (
        "rovlink calibrate: error: sending needs --yes when there is no terminal to ask on "
        "(--dry-run shows the values)"
    )
    assert server.fakes == []  # refused before the port opened


def test_given_readings_are_refused_for_what_is_wrong_with_them_before_yes_is_asked_for(
    run_cli: RunCli,
) -> None:
    # In a script (no terminal) without --yes. Before, the command said only that sending
    # needed --yes; with --yes added it then refused the readings: two runs to learn one fact.
    result = run_cli(
        "calibrate", "sim://", "--depth", "200", "--surface-raw", "120", "--depth-raw", "20"
    )
    assert result.status == 1
    assert result.err.splitlines()[-1].startswith(
        "rovlink calibrate: the readings are -100 counts apart (surface 120, at 200 cm 20)"
    )


def test_a_read_back_at_the_surface_says_it_cannot_show_the_values_were_taken(
    run_cli: RunCli,
) -> None:
    # The simulated sensor reads about 20 at the surface, below the new zero of 30: every
    # calibration reads 0 cm there, taken or dropped. Before, "depth now 0 cm" alone passed
    # for the read-back that shows the controller took them.
    result = run_cli(
        "calibrate", "sim://?seed=1", "--depth", "200", "--surface-raw", "30", "--depth-raw", "130",
        "--yes",
    )  # fmt: skip
    assert result.status == 0, result.err
    last = " ".join(result.out.split("\n")[-2:])
    assert last.startswith("sent #sdz.30! #sdk.200!; depth now 0 cm"), result.out
    assert "cannot show that the controller took them" in last


@pytest.mark.parametrize("depth_raw", ["120.55", "120.5", "130.449"])
def test_the_raw_reading_shown_reads_as_the_depth_shown(run_cli: RunCli, depth_raw: str) -> None:
    # Before, the raw was shown to one decimal and its depth computed from the unrounded
    # value: 120.55 was shown "raw 120.5 reads as 200 cm", where 120.5 reads as 199 cm.
    import re

    from rovlink.tuning.calibration import two_point

    arguments = ("--depth", "200", "--surface-raw", "20", "--depth-raw", depth_raw, "--dry-run")
    result = run_cli("calibrate", "sim://", *arguments)
    assert result.status == 0, result.err
    found = re.search(r"raw ([0-9.]+) reads as (\d+) cm", result.out)
    assert found is not None, result.out
    shown_raw, shown_cm = float(found[1]), int(found[2])
    assert two_point(20.0, float(depth_raw), 200).depth_for(shown_raw) == shown_cm
    assert abs(shown_raw - float(depth_raw)) < 0.01
