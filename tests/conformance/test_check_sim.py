"""``rovlink check`` against the simulator: every check passes; the table, JUnit and exit status."""

from __future__ import annotations

import os
import re
import select
import subprocess
import sys
import threading
import time
import tty
from pathlib import Path
from xml.etree import ElementTree

import pytest

from rovlink.cli import main
from rovlink.client.links import open_link
from rovlink.client.url import parse_url
from rovlink.conformance import (
    CHECKS,
    Outcome,
    Report,
    SuiteOptions,
    junit_xml,
    run_checks,
    select_checks,
)
from rovlink.conformance.results import CheckResult
from rovlink.conformance.wire import Exchange
from rovlink.protocol import COMMANDS


def test_every_command_of_the_table_has_a_check() -> None:
    names = {check.name for check in CHECKS}
    for spec in COMMANDS:
        if spec.is_query:
            assert f"query-{spec.name}" in names
        elif spec.name in ("crcon", "crcoff"):
            assert "checksum-mode-frames-exact" in names
        elif spec.name in ("start", "stop"):
            assert "start-stop-silent" in names
        else:
            assert f"set-{spec.name}" in names


@pytest.mark.integration
@pytest.mark.slow
def test_the_simulator_passes_every_check_with_motion() -> None:
    link = open_link(parse_url("sim://?seed=3"))
    try:
        report = run_checks(link, "sim://", SuiteOptions(motion=True))
    finally:
        link.close()
    assert [(r.name, r.message) for r in report.failures] == []
    assert len(report.results) == len(CHECKS)
    assert report.count(Outcome.PASSED) == len(CHECKS)


def test_select_checks_by_prefix_and_unknown_name() -> None:
    chosen = select_checks(["checksum-"])
    assert chosen
    assert all(check.name.startswith("checksum-") for check in chosen)
    assert all(not check.motion for check in select_checks())
    with pytest.raises(ValueError, match="no check is named 'nope'"):
        select_checks(["nope"])
    with pytest.raises(ValueError, match="an empty check name"):  # (it named every check)
        select_checks(["checksum-", ""])


def test_a_name_of_motion_checks_only_needs_motion() -> None:
    # Before, the name was looked up among all checks, then the motion ones were filtered out:
    # a run of no checks, which passed.
    with pytest.raises(ValueError, match=r"'motion-link' names only motion checks.*--motion"):
        select_checks(["motion-link"])
    with pytest.raises(ValueError, match="'motion-' names only motion checks"):
        select_checks(["query-qd", "motion-"])
    assert [check.name for check in select_checks(["motion-link"], motion=True)] == [
        "motion-link-loss-failsafe"
    ]


def test_a_run_of_no_checks_does_not_pass() -> None:
    assert not Report("nothing").passed
    skipped = CheckResult("motion-stop-halts", ("P7",), "d", Outcome.SKIPPED, "needs --motion")
    assert not Report("only skipped", [skipped]).passed
    link = open_link(parse_url("sim://?seed=2"))
    try:
        assert not run_checks(link, "sim://", SuiteOptions(), checks=[]).passed
    finally:
        link.close()


def test_cli_only_motion_checks_without_motion_is_a_usage_error(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["check", "sim://", "--only", "motion-link"]) == 2
    err = capsys.readouterr().err
    assert "'motion-link' names only motion checks: they run only with --motion" in err


@pytest.mark.parametrize(
    ("junit", "why"),
    [
        ("missing/check.xml", "no such directory"),
        ("a-file/check.xml", "not a directory"),
        (".", "is a directory"),
    ],
)
def test_cli_refuses_a_junit_path_it_cannot_write_before_running(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], junit: str, why: str
) -> None:
    # Before, the whole suite ran first (45 s with --motion), then the write failed.
    (tmp_path / "a-file").write_text("", encoding="utf-8")
    path = tmp_path / junit
    assert main(["check", "sim://", "--only", "query-qd", "--junit", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"--junit {path}: {why}" in err
    assert "query-qd" not in err  # (no check ran: its progress line is missing)


def test_junit_has_a_case_per_check_and_the_evidence_of_failures() -> None:
    evidence = (Exchange(sent=b"#qd!", received=b"$qd.007!"),)
    report = Report(
        "fake",
        [
            CheckResult("query-qd", ("P6",), "d", Outcome.FAILED, "not canonical", 0.1, evidence),
            CheckResult("query-qr", ("P4",), "d", Outcome.PASSED),
            CheckResult("motion-stop-halts", ("P7",), "d", Outcome.SKIPPED, "needs --motion"),
        ],
    )
    suite = ElementTree.fromstring(junit_xml(report))
    assert suite.get("tests") == "3"
    assert suite.get("failures") == "1"
    assert suite.get("skipped") == "1"
    (failure,) = suite.iter("failure")
    assert failure.get("message") == "not canonical"
    assert "b'$qd.007!'" in (failure.text or "")


@pytest.mark.integration
def test_cli_exit_status_table_and_junit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junit = tmp_path / "check.xml"
    status = main(["check", "sim://?seed=2", "--only", "query-", "--junit", str(junit)])
    out = capsys.readouterr().out
    assert status == 0
    assert "query-qsa" in out
    assert "checks passed" in out
    cases = list(ElementTree.parse(junit).getroot().iter("testcase"))
    assert len(cases) == len(select_checks(["query-"]))


@pytest.mark.parametrize(
    ("option", "too_low", "too_high", "shown"),
    [
        ("--timeout", "0.001", "11", "0.01–10"),
        ("--motion-power", "4", "51", "5–50"),
        ("--watchdog", "0.05", "61", "0.1–60"),
    ],
)
def test_help_gives_the_range_each_number_is_checked_against(
    capsys: pytest.CaptureFixture[str], option: str, too_low: str, too_high: str, shown: str
) -> None:
    # Before, --help gave the defaults alone: a user learnt the range from a refused value.
    for value in (too_low, too_high):
        assert main(["check", "sim://", option, value]) == 2
        assert f"argument {option}" in capsys.readouterr().err
    assert main(["check", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    described = text[text.index(f"{option} ", text.index("options:")) :]
    assert shown in described[: described.index("(default")], described[:200]


def test_cli_list_shows_the_checks_only_selects(capsys: pytest.CaptureFixture[str]) -> None:
    # Before, --only was ignored by --list: every check was listed, whatever it selected.
    assert main(["check", "--list", "--only", "checksum-bare", "--only", "motion-stop"]) == 0
    rows = capsys.readouterr().out.splitlines()[1:]  # (a row's further lines start blank)
    listed = [line.split()[0] for line in rows if line[:1] == " " and line[1:2] != " "]
    assert listed == ["checksum-bare-stop-accepted", "motion-stop-halts"], listed
    assert main(["check", "--list", "--only", "nope"]) == 2
    assert "no check is named 'nope'" in capsys.readouterr().err


def test_cli_list_and_usage_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--list"]) == 0
    assert "motion-stop-halts (--motion)" in capsys.readouterr().out
    assert main(["check"]) == 2
    assert "URL is required" in capsys.readouterr().err
    assert main(["check", "sim://", "--only", "nope"]) == 2


@pytest.mark.integration
def test_cli_motion_without_terminal_needs_yes() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "rovlink", "check", "sim://", "--motion"],
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
        timeout=60,
        check=False,
    )
    assert result.returncode == 2
    assert "--motion needs --yes" in result.stderr


def test_cli_motion_asks_only_when_a_selected_check_moves(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Regression: --motion with only non-motion checks selected still needed --yes (status 2).
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    assert main(["check", "sim://?seed=2", "--motion", "--only", "query-qd"]) == 0
    assert "query-qd" in capsys.readouterr().out
    assert main(["check", "sim://", "--motion", "--only", "query-qd", "--only", "motion-stop"]) == 2
    assert "--motion needs --yes" in capsys.readouterr().err


def test_docs_list_every_check() -> None:
    from rovlink.conformance import checks_markdown

    docs = Path(__file__).resolve().parents[2] / "docs" / "builders.md"
    assert checks_markdown() in docs.read_text(encoding="utf-8")


def test_docs_count_the_checks_a_run_without_motion_makes() -> None:
    # Regression: builders.md measured a noisy run as "of the 51 checks" when a run made 52.
    docs = (Path(__file__).resolve().parents[2] / "docs" / "builders.md").read_text("utf-8")
    counts = {int(count) for count in re.findall(r"of the (\d+) checks", docs)}
    assert counts == {len(select_checks(motion=False))}


@pytest.mark.integration
def test_a_leak_during_a_motion_check_stops_the_robot_and_aborts_the_run() -> None:
    from rovlink.client.links import PortLink
    from rovlink.sim.port import open_port

    port = open_port(seed=6, timeout=0.05)
    with port.lock:
        port.robot.inject_leak(at_s=port.robot.time_s + 2.0)
    link = PortLink(port, "sim")
    try:
        checks = select_checks(["motion-stop-halts", "motion-bare-stop"], motion=True)
        report = run_checks(link, "sim", SuiteOptions(motion=True), checks)
        (result,) = report.results  # the run stops at the abort
        assert result.outcome is Outcome.ABORTED
        assert "leak" in result.message
        with port.lock:
            assert port.controller.locked
            assert all(duty == 0 for duty in port.vehicle.duties)
    finally:
        link.close()


def test_preflight_refuses_a_silent_port_and_a_latched_leak() -> None:
    from rovlink.client.links import PortLink
    from rovlink.conformance import PreflightError
    from rovlink.sim.port import open_port

    echo = open_link(parse_url("loop://"))  # echoes commands back: no reply among them
    try:
        with pytest.raises(PreflightError, match=r"did not answer #q\.l! within 0\.5 s"):
            run_checks(echo, "loop://", SuiteOptions(boot_timeout_s=0.5))
    finally:
        echo.close()
    port = open_port(seed=1, timeout=0.05)
    with port.lock:
        port.robot.inject_leak()
    port.advance(0.1)
    link = PortLink(port, "sim")
    try:
        with pytest.raises(PreflightError, match="leak latch is set"):
            run_checks(link, "sim")
    finally:
        link.close()


@pytest.mark.integration
def test_cli_says_which_algorithm_the_controller_answers_with(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from tests.client.sim_process import running_sim

    # (A controller on a line, with its own algorithm: a sim:// one would take --algorithm.)
    with running_sim("--tcp", "127.0.0.1:0", "--speed", "0") as sim:
        assert sim.tcp_url is not None
        status = main(["check", sim.tcp_url, "--only", "checksum-replies", "--algorithm", "xor"])
    out = " ".join(capsys.readouterr().out.split())  # (the table's console wraps long lines)
    assert status == 1
    assert (
        "hint: the checksum checks got no reply with xor, but the controller answers #qd "
        "checksummed with crc8: run with --algorithm crc8"
    ) in out


def test_junit_carries_the_hint() -> None:
    report = Report("fake", hint="run with --algorithm crc8")
    root = ElementTree.fromstring(junit_xml(report))
    hints = [p.get("value") for p in root.iter("property") if p.get("name") == "hint"]
    assert hints == ["run with --algorithm crc8"]
    assert not [
        p
        for p in ElementTree.fromstring(junit_xml(Report("fake"))).iter("property")
        if p.get("name") == "hint"
    ]


def test_cli_summary_says_the_motion_checks_were_not_run(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Before, "50 of 50 checks passed" left out that #stop! and the failsafe went unchecked.
    from rovlink.cli.check import _motion_checks, _print_report

    motion = sum(check.motion for check in CHECKS)
    assert _motion_checks(None) == motion
    assert _motion_checks(["query-"]) == 0
    passed = CheckResult("query-qd", ("P4",), "d", Outcome.PASSED)
    _print_report(Report("sim://", [passed]), motion_not_run=motion)
    out = " ".join(capsys.readouterr().out.split())
    assert f"1 of 1 checks passed in 0.0 s; {motion} motion checks (#stop!, the link-loss " in out
    assert "failsafe) not run: add --motion" in out
    assert main(["check", "sim://?seed=2", "--only", "start-stop-silent"]) == 0
    assert "motion checks" not in capsys.readouterr().out  # (the selection has none)


def test_a_run_aborted_by_a_lost_link_says_which_checks_did_not_run(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Before, a run whose link died at the second of 8 checks ended "1 of 2 checks passed",
    # and its JUnit had 2 cases: as if the suite had no more checks.
    from rovlink.cli.check import _print_report
    from rovlink.client.links import PortLink
    from rovlink.sim.port import open_port

    port = open_port(seed=1, timeout=0.05)
    link = PortLink(port, "sim")
    checks = select_checks(["query-"])
    try:
        report = run_checks(link, "sim", SuiteOptions(), checks, on_result=lambda _: port.close())
    finally:
        link.close()
    first, second = report.results
    assert (first.outcome, second.outcome) == (Outcome.PASSED, Outcome.ABORTED)
    assert report.not_run == [check.name for check in checks[2:]]
    assert not report.passed
    _print_report(report)
    out = " ".join(capsys.readouterr().out.split())
    assert f"1 of 2 checks passed in {report.duration_s:.1f} s; 6 more not run: " in out
    assert f"{second.name} aborted the run" in out
    suite = ElementTree.fromstring(junit_xml(report))
    assert suite.get("tests") == str(len(checks))
    assert suite.get("skipped") == "6"
    skipped = [
        case.get("name") for case in suite.iter("testcase") if case.find("skipped") is not None
    ]
    assert skipped == report.not_run


@pytest.mark.integration
def test_a_link_lost_before_the_first_check_is_one_line(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Before, a controller that closed its socket at once made `rovlink check` end in a
    # traceback (ConnectionLostError from the preflight), and said nothing of why it closed.
    import socket
    import threading

    listener = socket.create_server(("127.0.0.1", 0))
    host, port = listener.getsockname()[:2]

    def close_at_once() -> None:
        connection, _ = listener.accept()
        connection.sendall(b"busy: the controller already has a client\r\n")
        # Closed for writing only, and read to the end: a close with unread bytes resets the
        # connection, and the line could be lost with it.
        connection.shutdown(socket.SHUT_WR)
        connection.settimeout(5.0)
        with connection:
            while connection.recv(4096):
                pass

    closer = threading.Thread(target=close_at_once, daemon=True)
    closer.start()
    try:
        assert main(["check", f"socket://{host}:{port}"]) == 1
    finally:
        closer.join(5.0)
        listener.close()
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(
        f"rovlink check: socket://{host}:{port}: the link was lost before the first check: "
    )
    # What it said when it turned the suite away (before, the line left it out).
    assert err[-1].endswith('; it said: "busy: the controller already has a client"')
    assert "Traceback" not in "\n".join(err)


@pytest.mark.integration
@pytest.mark.parametrize(
    ("url", "why"),
    [
        ("sim://?leak_at=0", "the leak latch is set"),
        ("socket://127.0.0.1:{port}", "cannot open socket://127.0.0.1:"),
    ],
)
def test_a_run_that_cannot_start_leaves_a_junit_file_that_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], url: str, why: str
) -> None:
    # Before, the file an earlier run wrote was left as it was: a CI read its results (every
    # check passed) as this run's.
    import socket

    with socket.socket() as unused:  # a port nothing listens on
        unused.bind(("127.0.0.1", 0))
        url = url.format(port=unused.getsockname()[1])
    junit = tmp_path / "check.xml"
    junit.write_text('<testsuite name="rovlink check" tests="50" failures="0"/>', encoding="utf-8")
    assert main(["check", url, "--junit", str(junit)]) == 1
    line = capsys.readouterr().err.strip().splitlines()[-1]
    suite = ElementTree.parse(junit).getroot()
    assert (suite.get("tests"), suite.get("errors"), suite.get("failures")) == ("1", "1", "0")
    (case,) = suite.iter("testcase")
    assert case.get("name") == "preflight"
    error = case.find("error")
    assert error is not None
    message = error.get("message") or ""
    assert why in message
    assert line == f"rovlink check: {message}"


def test_an_interrupted_run_leaves_a_junit_file_that_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # Ctrl-C, or a CI job's timeout (SIGTERM, taken as Ctrl-C), during the second check.
    # Before, the file an earlier run wrote was left as it was, read as this run's results.
    from rovlink.cli import check as check_command

    progress = check_command._progress
    seen: list[str] = []

    def interrupted_at_the_second(result: CheckResult) -> None:
        progress(result)
        seen.append(result.name)
        if len(seen) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(check_command, "_progress", interrupted_at_the_second)
    junit = tmp_path / "check.xml"
    junit.write_text('<testsuite name="rovlink check" tests="50" failures="0"/>', encoding="utf-8")
    assert main(["check", "sim://?seed=2", "--only", "query-", "--junit", str(junit)]) == 130
    assert capsys.readouterr().err.strip().splitlines()[-1] == "rovlink check: interrupted"
    suite = ElementTree.parse(junit).getroot()
    selected = [check.name for check in select_checks(["query-"])]
    assert (suite.get("tests"), suite.get("errors")) == (str(len(selected) + 1), "1")
    cases = {case.get("name"): case for case in suite.iter("testcase")}
    assert list(cases) == [*seen, "interrupted", *selected[2:]]
    error = cases["interrupted"].find("error")
    assert error is not None
    assert error.get("message") == "the run was interrupted (Ctrl-C or a signal)"
    for name in selected[2:]:
        skipped = cases[name].find("skipped")
        assert skipped is not None
        assert skipped.get("message") == "not run: the run was interrupted (Ctrl-C or a signal)"
    # The run's time, not "0.000": at least the time of the checks that ended. (Before, the
    # suite said the run took no time, under cases that each took some.)
    ended_s = sum(float(cases[name].get("time") or "nan") for name in seen)
    assert ended_s > 0
    assert float(suite.get("time") or "nan") >= ended_s - 0.002  # (each rounded to 1 ms)


def test_the_summary_names_the_settings_left_at_test_values(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Before, only the docs said so: a run left the PWM cap at 0 and the calibration at test
    # values, and the next tool (rovlink tune) drove a vehicle whose thrust or depth was wrong.
    assert main(["check", "sim://?seed=2", "--only", "set-sdz", "--only", "set-mgmp"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert (
        "the checks set mgmp, sdz to test values, which no query reads back: reset the "
        "controller (or set them again) before using it"
    ) in out
    assert main(["check", "sim://?seed=2", "--only", "query-qd"]) == 0
    assert "test values" not in capsys.readouterr().out


def test_ctrl_c_during_a_dive_leaves_the_robot_locked_with_zero_thrust(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Ctrl-C (or SIGTERM, taken as Ctrl-C) lands while a motion check watches the vehicle dive.
    import time
    from types import SimpleNamespace

    from rovlink.client.links import PortLink
    from rovlink.conformance import motion
    from rovlink.sim.port import open_port

    port = open_port(seed=6, timeout=0.05)

    def sleep(seconds: float) -> None:
        with port.lock:
            diving = not port.controller.locked and any(port.vehicle.duties)
        if diving:
            raise KeyboardInterrupt
        time.sleep(seconds)

    monkeypatch.setattr(motion, "time", SimpleNamespace(monotonic=time.monotonic, sleep=sleep))
    link = PortLink(port, "sim")
    try:
        with pytest.raises(KeyboardInterrupt):
            run_checks(
                link,
                "sim",
                SuiteOptions(motion=True),
                select_checks(["motion-stop-halts"], motion=True),
            )
        with port.lock:
            assert port.controller.locked
            assert all(duty == 0 for duty in port.vehicle.duties)
    finally:
        link.close()


class _LateOnAPseudoTerminal:
    """A controller on a real pseudo-terminal that answers ``#qd!`` 5.5 ms late (and the
    preflight's ``#q.l!`` at once)."""

    LATE_S = 0.0055

    def __init__(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        pending = b""
        while not self._closing.is_set():
            if not select.select([self._master], [], [], 0.05)[0]:
                continue
            try:
                pending += os.read(self._master, 4096)
            except OSError:
                return
            *frames, pending = pending.split(b"!")
            for frame in frames:
                if frame.endswith(b"#q.l"):
                    os.write(self._master, b"$q.l.0!")
                elif frame.endswith(b"#qd"):
                    time.sleep(self.LATE_S)
                    os.write(self._master, b"$qd.5!")

    def close(self) -> None:
        self._closing.set()
        self._thread.join()
        os.close(self._master)
        os.close(self._slave)


@pytest.mark.integration
@pytest.mark.realtime  # (a busy machine adds its own lateness to the 5.5 ms)
def test_a_reply_late_on_a_pseudo_terminal_is_late(capsys: pytest.CaptureFixture[str]) -> None:
    # A pseudo-terminal's bytes take no time on a line, whatever its baud rate: before, the
    # check allowed for 115200 baud's 0.9 ms on it, and a simulator or a firmware's host build
    # answering 5.5 ms late passed P19's 5 ms.
    controller = _LateOnAPseudoTerminal()
    try:
        assert main(["check", controller.path, "--only", "reply-time"]) == 1
    finally:
        controller.close()
    out = " ".join(capsys.readouterr().out.split())  # (the report wraps its lines)
    assert "fail reply-time: 90th percentile reply time" in out
    assert "> 5 ms (median" in out  # (no allowance for bytes on a line)
