"""``rovlink tune`` on the command line."""

from __future__ import annotations

import argparse
import errno
import io
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import pytest

from rovlink.cli import main
from rovlink.cli.failure import UsageError
from rovlink.cli.tune import parse_triple


@pytest.fixture
def nothing_connects(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if the command opens its link: what it refuses, it refuses before."""
    from rovlink.cli import link_options

    def refuse(args: argparse.Namespace) -> None:
        raise AssertionError("connected")

    monkeypatch.setattr(link_options, "connect", refuse)


def test_list_rules_and_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["tune", "sim://", "--list-rules"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert listed[0].startswith("simc ")
    assert listed[0].endswith("(default)")
    assert any(line.startswith("heave-poles ") for line in listed)
    assert main(["tune", "sim://", "--rule", "magic", "--yes"]) == 2
    assert "unknown rule 'magic'" in capsys.readouterr().err
    assert main(["tune", "sim://", "--depth", "500", "--max-depth", "300", "--yes"]) == 2
    assert "--depth 500 must lie strictly between --min-depth 20 and --max-depth 300" in (
        capsys.readouterr().err
    )
    assert main(["tune", "sim://", "--min-depth", "300", "--max-depth", "200", "--yes"]) == 2
    assert "0 ≤ min < max" in capsys.readouterr().err


def test_help_shows_the_depth_limits_defaults(capsys: pytest.CaptureFixture[str]) -> None:
    # Regression: the limits a --depth is refused for were in neither the error nor the help.
    assert main(["tune", "--help"]) == 0
    help_text = " ".join(capsys.readouterr().out.split())  # (however argparse wrapped it)
    assert "--min-depth CM shallowest allowed, cm (default: 20)" in help_text
    assert "--max-depth CM deepest allowed, cm (default: 300)" in help_text


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


def test_gains_that_cannot_be_sent_at_the_end_are_one_line(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, a link lost just as the gains were sent back ended in a traceback.
    from rovlink.client import Client, ConnectionLostError
    from rovlink.protocol import Command
    from rovlink.tuning import ProtocolGains

    tuned = SimpleNamespace(gains=ProtocolGains(55, 20, 10), step=None)  # (--no-verify)
    monkeypatch.setattr("rovlink.tuning.autotune", lambda *_, **__: tuned)
    send = Client.send

    def lost_after_the_first_gain(client: Client, command: Command) -> object:
        if command.name != "mvpdp":
            raise ConnectionLostError("connection lost: closed by the other end")
        return send(client, command)

    monkeypatch.setattr(Client, "send", lost_after_the_first_gain)
    assert main(["tune", "sim://", "--yes", "--no-verify", "--apply"]) == 1
    assert capsys.readouterr().err == (
        "rovlink tune: the experiment ended, but #mvpdi.20! could not be sent (only "
        "#mvpdp.55! went; the depth PID is not as asked: tune again or set it): connection "
        "lost: closed by the other end\n"
    )


@pytest.mark.parametrize(
    ("argv", "error"),
    [
        (
            ["--step-from", "500"],
            "--step-from 500 must lie between --min-depth 20 and --max-depth 300",
        ),
        (
            ["--step-from", "10"],
            "--step-from 10 must lie between --min-depth 20 and --max-depth 300",
        ),
        (["--step-from", "100"], "--step-from 100 is --depth: the step would not move"),
    ],
)
def test_a_step_outside_the_limits_is_refused_before_anything_is_sent(
    nothing_connects: None,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    error: str,
) -> None:
    # Before, --step-from 500 with --max-depth 300 was taken, and the step drove past the limit.
    assert main(["tune", "sim://", "--yes", *argv]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"rovlink tune: error: {error}"


@pytest.mark.parametrize(
    ("argv", "error"),
    [
        (
            ["--depth", "21"],
            "--depth 21 ± --hysteresis 3 (the relay switches past 18 and 24 cm) must lie "
            "strictly between --min-depth 20 and --max-depth 300",
        ),
        (
            ["--depth", "40", "--hysteresis", "20"],
            "--depth 40 ± --hysteresis 20 (the relay switches past 20 and 60 cm) must lie "
            "strictly between --min-depth 20 and --max-depth 300",
        ),
        (
            ["--depth", "290", "--hysteresis", "10"],
            "--depth 290 ± --hysteresis 10 (the relay switches past 280 and 300 cm) must lie "
            "strictly between --min-depth 20 and --max-depth 300",
        ),
    ],
)
def test_a_relay_that_would_run_into_a_limit_is_refused_before_anything_is_sent(
    nothing_connects: None,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    error: str,
) -> None:
    # Before, --depth 21 (--min-depth 20, --hysteresis 3) ran the motors until the vehicle
    # rose past 18 cm, where the relay turns, and aborted there: above the limit, every time.
    assert main(["tune", "sim://", "--yes", "--no-verify", *argv]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"rovlink tune: error: {error}"


def test_a_simulator_faster_than_real_time_is_refused_before_anything_is_sent(
    nothing_connects: None, capsys: pytest.CaptureFixture[str]
) -> None:
    # Before, `rovlink tune 'sim://?realtime=0'` ran: the simulated watchdog locked the motors
    # between two wall-clock samples, and the relay ran for 2 minutes to "no steady
    # oscillation within 120 s".
    assert main(["tune", "sim://?seed=1&realtime=0", "--yes"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "rovlink tune: error: sim://?seed=1&realtime=0: realtime=0 runs the simulation faster "
        "than the tune's clock, and its link-loss failsafe (P17) locks the motors between two "
        "samples; leave realtime on"
    )


def test_a_simulator_faster_than_real_time_behind_a_noisy_link_is_refused(
    nothing_connects: None, capsys: pytest.CaptureFixture[str]
) -> None:
    # Before, fault:// around sim://?realtime=0 ran: the simulated watchdog locked the motors
    # between two samples, and the relay aborted blaming the depth sensor.
    url = "fault://?inner=sim%3A%2F%2F%3Frealtime%3D0&seed=1"
    assert main(["tune", url, "--yes"]) == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"rovlink tune: error: {url}: realtime=0 runs the simulation faster than the tune's "
        "clock, and its link-loss failsafe (P17) locks the motors between two samples; leave "
        "realtime on"
    )


def test_the_default_step_starts_well_inside_the_limits() -> None:
    # Before, the step from 1 m above a 100 cm target started at 0 cm, above --min-depth 20;
    # then at 20 cm, which the hold's approach overshot (to 6-10 cm on the simulated
    # vehicles), unseen, as the verification did not keep to the shallow limit.
    from rovlink.cli.tune import _step_from

    limits = {"min_depth": 20, "max_depth": 300, "step_from": None}
    assert _step_from(argparse.Namespace(depth=100, **limits)) == 40
    assert _step_from(argparse.Namespace(depth=250, **limits)) == 150
    assert _step_from(argparse.Namespace(depth=30, **limits)) == 130  # no room above: below
    assert _step_from(argparse.Namespace(depth=270, **limits)) == 170
    with pytest.raises(UsageError, match="--depth 50 leaves no room for the verification's step"):
        _step_from(argparse.Namespace(depth=50, min_depth=40, max_depth=60, step_from=None))


@pytest.mark.parametrize(
    ("plot", "error"),
    [
        ("tune.txt", "--plot {tmp}/tune.txt: name the image format by its suffix: .png, .svg"),
        ("tune", "--plot {tmp}/tune: name the image format by its suffix: .png, .svg"),
        ("missing/tune.png", "--plot {tmp}/missing/tune.png: no such directory: {tmp}/missing"),
        ("a-directory.png", "--plot {tmp}/a-directory.png: is a directory"),
    ],
)
def test_a_plot_that_cannot_be_written_is_refused_before_anything_is_sent(
    nothing_connects: None,
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    plot: str,
    error: str,
) -> None:
    # Before, --plot was first looked at after the experiment (minutes of the motors running):
    # a directory not there was one line then, a name without an image suffix a traceback.
    (tmp_path / "a-directory.png").mkdir()
    assert main(["tune", "sim://", "--yes", "--plot", f"{tmp_path}/{plot}"]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith(f"rovlink tune: error: {error.format(tmp=tmp_path)}")


@pytest.mark.integration
@pytest.mark.parametrize("ending", ["abort", "ctrl-c"])
def test_an_aborted_tune_sends_the_gains_back(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], ending: str
) -> None:
    # An abort during the verification (a leak, a limit, Ctrl-C): before, the gains it was
    # trying were left set, though without --apply the --restore gains are sent back.
    from rovlink.tuning import Plant, TuneAbortedError
    from tests.client.conftest import CONDITION_TIMEOUT_S, wait_until
    from tests.client.fake_controller import FakeControllerServer

    def aborted_in_the_verification(plant: Plant, *args: object, **kwargs: object) -> None:
        plant.client.set_depth_pid(90, 91, 92)  # the gains being verified
        plant.stop()
        if ending == "ctrl-c":
            raise KeyboardInterrupt
        raise TuneAbortedError("the leak sensor fired: #stop! sent")

    monkeypatch.setattr("rovlink.tuning.autotune", aborted_in_the_verification)
    server = FakeControllerServer()
    try:
        status = main(["tune", server.url, "--yes", "--boot-timeout", "0"])
        assert wait_until(lambda: len(server.fakes) == 1)
        assert server.ended[0].wait(CONDITION_TIMEOUT_S)
        frames = server.fakes[0].frames()
    finally:
        server.close()
    err = capsys.readouterr().err.strip().splitlines()
    last = err[-1]
    if ending == "ctrl-c":
        assert (status, last) == (130, "rovlink tune: interrupted")
        # Said what became of the motors and the gains (before, only "interrupted").
        assert err[-2] == "#stop! sent; gains sent back: mvpdp 40, mvpdi 30, mvpidd 20"
    else:
        assert status == 1
        assert last == (
            "rovlink tune: aborted: the leak sensor fired: #stop! sent; gains sent back: "
            "mvpdp 40, mvpdi 30, mvpidd 20"
        )
    gains = [frame for frame in frames if frame.startswith("#mvp")]
    assert gains[-3:] == ["#mvpdp.40!", "#mvpdi.30!", "#mvpidd.20!"]


def _result_missing_the_settling_target() -> object:
    from rovlink.tuning import ProtocolGains, StepResult, StepSettings

    settings = StepSettings(from_cm=40, to_cm=100)
    # Still 10 cm off the target 12 s after the step: the 10 s settling target is missed.
    times_s = [step * 0.5 for step in range(150)]
    depths_cm = [90 if time_s <= 12.0 else 100 for time_s in times_s]
    step = StepResult(settings, times_s, depths_cm)
    relay = SimpleNamespace(
        ultimate_gain=2.4, ultimate_period_s=4.0, amplitude_cm=16.0, bias_percent=-8.8
    )
    physical = SimpleNamespace(kp=2.9, ki=0.39, kd=3.4)
    rule = SimpleNamespace(name="heave-poles", description="mass model")
    return SimpleNamespace(
        relay=relay, rule=rule, physical=physical, gains=ProtocolGains(58, 78, 34), step=step
    )


def _sent_frames(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The frames the blocking client's ``send`` will send, as they go."""
    from rovlink.client import Client
    from rovlink.protocol import Command

    sent: list[str] = []
    send = Client.send

    def recorded(client: Client, command: Command) -> object:
        sent.append(str(command))
        return send(client, command)

    monkeypatch.setattr(Client, "send", recorded)
    return sent


def test_apply_leaves_no_gains_set_that_missed_the_verifications_targets(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, --apply left the tuned gains set even when their step missed a target: gains
    # that held the depth worse than the ones they replaced flew the next dive.
    monkeypatch.setattr(
        "rovlink.tuning.autotune", lambda *_, **__: _result_missing_the_settling_target()
    )
    sent = _sent_frames(monkeypatch)
    assert main(["tune", "sim://", "--yes", "--apply"]) == 1
    assert sent == ["#mvpdp.40!", "#mvpdi.30!", "#mvpidd.20!"]
    out = capsys.readouterr().out
    assert "within ±3 cm after 12.0 s (target ≤ 10)" in out
    assert out.splitlines()[-1] == (
        "gains not applied (--apply: the verification missed a target); sent back mvpdp 40, "
        "mvpdi 30, mvpidd 20; motors locked"
    )


def test_apply_leaves_gains_set_that_met_the_targets(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    result = _result_missing_the_settling_target()
    result.step.depths_cm[:] = [100] * len(result.step.depths_cm)  # type: ignore[attr-defined]
    monkeypatch.setattr("rovlink.tuning.autotune", lambda *_, **__: result)
    sent = _sent_frames(monkeypatch)
    assert main(["tune", "sim://", "--yes", "--apply"]) == 0
    assert sent == ["#mvpdp.58!", "#mvpdi.78!", "#mvpidd.34!"]
    assert capsys.readouterr().out.splitlines()[-1] == "gains applied; motors locked"


@pytest.mark.integration
def test_a_plot_whose_format_needs_a_missing_program_is_one_line_after_the_gains_went_back(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    # Before, a traceback: matplotlib's .pgf needs LaTeX ("'xelatex' not found").
    pytest.importorskip("matplotlib", reason="matplotlib is in the test extra (plot)")
    result = _result_missing_the_settling_target()
    result.relay.times_s = [0.0, 1.0, 2.0]  # type: ignore[attr-defined]
    result.relay.depths_cm = [100, 104, 98]  # type: ignore[attr-defined]
    result.relay.outputs_percent = [30, -30, 30]  # type: ignore[attr-defined]
    monkeypatch.setattr("rovlink.tuning.autotune", lambda *_, **__: result)
    sent = _sent_frames(monkeypatch)
    monkeypatch.setenv("PATH", str(tmp_path))  # (no LaTeX there, installed or not)
    image = tmp_path / "tune.pgf"
    assert main(["tune", "sim://", "--yes", "--plot", str(image)]) == 1
    assert sent == ["#mvpdp.40!", "#mvpdi.30!", "#mvpidd.20!"]  # the gains went back first
    err = capsys.readouterr().err
    assert err.startswith(f"rovlink tune: cannot write {image}: ")
    assert "not found" in err
    assert "Traceback" not in err
    assert not image.exists()


def test_the_experiment_is_said_on_stderr_as_it_goes(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Before, `rovlink tune` said nothing for the minutes its motors ran.
    heard: list[str] = []

    def tuned(*_: object, progress: Callable[[str], None]) -> object:
        progress("motors unlocked: relay of ±30 % vertical thrust around 100 cm (up to 120 s)")
        heard.append(capsys.readouterr().err)  # on the terminal before the experiment ends
        result = _result_missing_the_settling_target()
        result.step = None  # type: ignore[attr-defined]
        return result

    monkeypatch.setattr("rovlink.tuning.autotune", tuned)
    assert main(["tune", "sim://", "--yes", "--no-verify"]) == 0
    assert heard == [
        "motors unlocked: relay of ±30 % vertical thrust around 100 cm (up to 120 s)\n"
    ]
    assert capsys.readouterr().out.splitlines()[-1].endswith("motors locked")


def test_an_interrupt_while_the_gains_are_sent_at_the_end_says_which_went(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Ctrl-C (or SIGTERM, taken as it) lands as the gains to leave set go, one frame at a time,
    # after the experiment's #stop!. Before, only "interrupted": nothing said that the depth
    # PID was left half as tuned and half as before.
    from rovlink.client import Client
    from rovlink.protocol import Command
    from rovlink.tuning import ProtocolGains

    tuned = SimpleNamespace(gains=ProtocolGains(55, 20, 10), step=None)  # (--no-verify)
    monkeypatch.setattr("rovlink.tuning.autotune", lambda *_, **__: tuned)
    send = Client.send

    def interrupted_after_the_first_gain(client: Client, command: Command) -> object:
        if command.name != "mvpdp":
            raise KeyboardInterrupt
        return send(client, command)

    monkeypatch.setattr(Client, "send", interrupted_after_the_first_gain)
    assert main(["tune", "sim://", "--yes", "--no-verify", "--apply"]) == 130
    assert capsys.readouterr().err.splitlines() == [
        "interrupted while #mvpdi.20! was sent (only #mvpdp.55! went before it; the depth PID "
        "may not be as asked: tune again or set it)",
        "rovlink tune: interrupted",
    ]


class _ClosedTerminal(io.TextIOBase):
    """The standard error of a closed terminal (SIGHUP): every write fails."""

    def writable(self) -> bool:
        return True

    def write(self, text: str, /) -> int:
        raise OSError(errno.EIO, "Input/output error")


def test_a_closed_terminal_ends_an_interrupted_tune_with_130(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # SIGHUP (a closed terminal or SSH session) ends the command as Ctrl-C does (status 130),
    # after #stop! and the gains sent back. Before, the line saying so failed to be written
    # and its OSError ended the command instead, in a traceback with status 1.
    from rovlink.tuning import Plant

    def interrupted(plant: Plant, *args: object, **kwargs: object) -> None:
        plant.client.start()
        raise KeyboardInterrupt

    monkeypatch.setattr("rovlink.tuning.autotune", interrupted)
    sent = _sent_frames(monkeypatch)
    monkeypatch.setattr("sys.stderr", _ClosedTerminal())
    assert main(["tune", "sim://", "--yes"]) == 130
    assert sent == ["#mvpdp.40!", "#mvpdi.30!", "#mvpidd.20!"]
