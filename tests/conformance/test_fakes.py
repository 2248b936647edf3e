"""Each deliberately broken controller is caught by the check named for its fault."""

from __future__ import annotations

import queue
import re
import threading
import time
from pathlib import Path

import pytest

from rovlink.client.links import PortLink
from rovlink.conformance import (
    Outcome,
    PreflightError,
    Report,
    SuiteOptions,
    run_checks,
    select_checks,
)
from rovlink.protocol import get_algorithm
from tests.conformance.fakes import FAULTS, NO_FAULT, FaultyController

_FAST = [name for name, check in FAULTS.items() if not check.startswith("motion-")]


@pytest.mark.parametrize("fault", _FAST)
def test_each_fault_is_caught_by_its_check(fault: str) -> None:
    expected = FAULTS[fault]
    link = PortLink(FaultyController(fault), fault)
    try:
        report = run_checks(link, fault, SuiteOptions(), select_checks([expected]))
    finally:
        link.close()
    results = {result.name: result for result in report.results}
    assert results[expected].failed, results[expected]  # (or aborted: hangs-on-overlong)
    assert results[expected].evidence  # the bytes that show it
    assert not report.passed


_MOTION = [name for name, check in FAULTS.items() if check.startswith("motion-")]


# Real-time motion (each watches the depth for seconds): on the newest Python only, as slow.
@pytest.mark.slow
@pytest.mark.integration
@pytest.mark.parametrize("fault", _MOTION)
def test_each_motion_fault_is_caught_by_its_motion_check(fault: str) -> None:
    expected = FAULTS[fault]
    link = PortLink(FaultyController(fault), fault)
    try:
        report = run_checks(
            link, fault, SuiteOptions(motion=True), select_checks([expected], motion=True)
        )
    finally:
        link.close()
    (result,) = report.results
    assert result.name == expected
    assert result.failed, result  # (failed, or aborted the run: see ignores-stop below)


def _motion_run(fault: str, names: list[str]) -> Report:
    link = PortLink(FaultyController(fault), fault)
    try:
        return run_checks(link, fault, SuiteOptions(motion=True), select_checks(names, motion=True))
    finally:
        link.close()


@pytest.mark.slow
@pytest.mark.integration
def test_a_motion_check_that_fails_with_the_vehicle_diving_leaves_it_at_rest_for_the_next() -> None:
    # The bare #stop! is ignored in checksum mode: the check fails with the vehicle still
    # diving. Before, the next check started while it coasted on and took that dive for its
    # own: a full run failed the mode gating (P9) and the PWM cap (P8) too, rules the
    # controller obeys.
    report = _motion_run("stop-needs-checksum", ["motion-bare-stop", "motion-out-of-range"])
    assert [(result.name, result.outcome) for result in report.results] == [
        ("motion-bare-stop-in-checksum-mode", Outcome.FAILED),
        ("motion-out-of-range-not-clamped", Outcome.PASSED),
    ], report.results
    # The evidence is still the failure's: the pressure rising after the #stop!.
    assert b"#q.l" in report.results[0].evidence[-1].sent


@pytest.mark.slow
@pytest.mark.integration
def test_a_vehicle_still_diving_after_a_failed_checks_stop_aborts_the_run() -> None:
    # #stop! has no effect at all: more motion checks would only drive it deeper.
    report = _motion_run("ignores-stop", ["motion-stop-halts", "motion-mode-gating"])
    (result,) = report.results
    assert result.outcome is Outcome.ABORTED, result
    assert result.message.startswith("after #stop! the raw pressure went on"), result.message
    assert "still went deeper" in result.message, result.message
    assert report.not_run == ["motion-mode-gating"]


@pytest.mark.slow
@pytest.mark.integration
def test_a_plain_stop_still_works_on_the_controller_that_needs_a_checksummed_one() -> None:
    link = PortLink(FaultyController("stop-needs-checksum"), "stop-needs-checksum")
    try:
        report = run_checks(
            link,
            "fake",
            SuiteOptions(motion=True),
            select_checks(["motion-stop-halts"], motion=True),
        )
    finally:
        link.close()
    assert [result.outcome for result in report.results] == [Outcome.PASSED]


def test_a_controller_that_stops_answering_aborts_the_run_at_the_check_it_failed() -> None:
    # Before, every later check waited for its replies in vain and failed "no reply" (50 of 51
    # in about a minute against a controller that hung), and the run ended with a hint that the
    # controller might have no checksum mode.
    fault = "hangs-on-overlong"
    link = PortLink(FaultyController(fault), fault)
    try:
        report = run_checks(
            link, fault, SuiteOptions(), select_checks(["overlong-", "resync-", "bad-byte-"])
        )
    finally:
        link.close()
    (result,) = report.results
    assert result.name == "overlong-frame-dropped"
    assert result.outcome is Outcome.ABORTED, result
    assert "no reply" in result.message  # the check's own failure first
    assert result.message.endswith(
        "; then a plain #q.l! got no reply within 3 s either: the controller stopped answering "
        "(hung, or reset and not back), run aborted"
    ), result.message
    assert report.not_run == ["resync-on-start", "bad-byte-discards"]
    assert report.hint is None


def test_every_fault_names_a_real_check() -> None:
    names = {check.name for check in select_checks(motion=True)}
    assert set(FAULTS.values()) <= names


def test_docs_list_every_broken_controller_with_the_check_that_catches_it() -> None:
    # Before, no-checksum-mode and uppercase-checksums-only were tested and not listed.
    docs = (Path(__file__).resolve().parents[2] / "docs" / "builders.md").read_text()
    section = docs.split("### The broken controllers", 1)[1].split("\n## ", 1)[0]
    rows = dict(re.findall(r"^\| `([a-z0-9-]+)` \| .* \| `([a-z0-9.+-]+)` \|$", section, re.M))
    assert rows == FAULTS


@pytest.mark.integration
@pytest.mark.slow
def test_the_wrapper_without_a_fault_passes_every_check() -> None:
    link = PortLink(FaultyController(NO_FAULT), NO_FAULT)
    try:
        report = run_checks(link, NO_FAULT)
    finally:
        link.close()
    assert [result.name for result in report.failures] == []
    assert len(report.results) == len(select_checks())


@pytest.mark.realtime
def test_reply_time_allows_for_the_bytes_on_a_slow_line() -> None:
    # 15 ms late is too slow on a fast link, but at 4800 baud the query and its reply spend
    # about 23 ms on the wire, which P19 does not count (it counts from the query's arrival);
    # the margin leaves room for a loaded machine's scheduling.
    link = PortLink(FaultyController("slow-replies"), "slow")
    try:
        report = run_checks(link, "slow", SuiteOptions(baudrate=4800), select_checks(["reply-"]))
    finally:
        link.close()
    assert [result.outcome for result in report.results] == [Outcome.PASSED]


def _checksum_run(link: PortLink, algorithm: str) -> Report:
    try:
        return run_checks(
            link, "fake", SuiteOptions(algorithm=algorithm), select_checks(["checksum-replies"])
        )
    finally:
        link.close()


@pytest.mark.parametrize("given", ["xor", "sum8"])
def test_a_run_with_another_algorithm_than_the_controllers_names_the_controllers(
    given: str,
) -> None:
    # The simulated controller checksums with crc8: every checksummed frame of the run is
    # dropped, which alone reads as a controller without a checksum mode.
    report = _checksum_run(PortLink(FaultyController(NO_FAULT), NO_FAULT), given)
    assert "no reply" in report.failures[0].message
    assert report.hint == (
        f"the checksum checks got no reply with {given}, but the controller answers #qd "
        "checksummed with crc8: run with --algorithm crc8"
    )


def test_a_controller_without_a_checksum_mode_is_told_apart_from_a_wrong_algorithm() -> None:
    report = _checksum_run(
        PortLink(FaultyController("no-checksum-mode"), "no-checksum-mode"), "crc8"
    )
    assert report.hint == (
        "the checksum checks got no reply with crc8, nor does the controller answer #qd "
        "checksummed with sum8 or xor: has it a checksum mode (P3)?"
    )


def test_no_hint_when_the_controller_answers_with_the_runs_algorithm() -> None:
    # Its only fault is refusing lowercase checksums: "no reply" there is that, not the algorithm.
    fault = "uppercase-checksums-only"
    link = PortLink(FaultyController(fault), fault)
    try:
        report = run_checks(
            link, "fake", SuiteOptions(), select_checks(["checksum-lowercase-accepted"])
        )
    finally:
        link.close()
    assert "no reply" in report.failures[0].message
    assert report.hint is None


def test_no_hint_when_the_checksum_checks_pass_or_fail_otherwise() -> None:
    passing = _checksum_run(PortLink(FaultyController(NO_FAULT), NO_FAULT), "crc8")
    assert passing.passed
    assert passing.hint is None
    plain = "plain-replies-in-checksum-mode"  # fails with a reply, not for want of one
    failing = _checksum_run(PortLink(FaultyController(plain), plain), "crc8")
    assert not failing.passed
    assert failing.hint is None


def test_a_late_reply_is_named_and_kept_out_of_the_next_check() -> None:
    # A controller that answers 100 ms late, run with a 50 ms reply timeout. Before, each
    # reply landed in the next query's wait: "expected $qr; got $qd", as if #qr! were answered
    # by $qd, and a check could pass on the late reply of an earlier one.
    link = PortLink(FaultyController(NO_FAULT, late_s=0.1), "late")
    options = SuiteOptions(reply_timeout_s=0.05)
    try:
        report = run_checks(link, "late", options, select_checks(["query-qd", "query-qr"]))
    finally:
        link.close()
    for result in report.results:
        name = result.name.removeprefix("query-")
        assert result.outcome is Outcome.FAILED
        assert result.message.startswith(
            f"expected ${name}; no reply within 50 ms; ${name} came late"
        )
        assert "P19 allows 5 ms" in result.message


def test_the_debug_lines_of_a_controller_150_ms_away_stay_out_of_the_next_check() -> None:
    # The runner puts the controller back (debug off) between checks, and start-stop-silent
    # fails on any byte. Before, that restore waited for a fixed 100 ms of quiet: the lines a
    # controller 150 ms away wrote for its #stop! and #debug0! came after it, and in a run that
    # put start-stop-silent after a debug check, a correct controller failed it ("with debug
    # off nothing at all"). The restore now waits for the reply to a #qd! sent after it (P20's
    # fence). (The suite's own order puts no such check after a debug one.)
    link = PortLink(FaultyController(NO_FAULT, late_s=0.15), "150 ms away")
    options = SuiteOptions(silence_s=0.3)  # (the checks' own silences allow for the distance)
    checks = select_checks(["debug-text-clean"]) + select_checks(["start-stop-silent"])
    try:
        report = run_checks(link, "far", options, checks)
    finally:
        link.close()
    assert [(result.name, result.outcome, result.message) for result in report.results] == [
        ("debug-text-clean", Outcome.PASSED, ""),
        ("start-stop-silent", Outcome.PASSED, ""),
    ]


def test_the_restore_waits_for_its_fence_as_long_as_for_a_late_reply() -> None:
    # A controller 0.5 s away, checked with --timeout 0.6: the restore's fence is answered
    # after 0.5 s, which it waits for (three reply timeouts), so the $qd does not land in the
    # next check as an answer to a setting.
    link = PortLink(FaultyController(NO_FAULT, late_s=0.5), "0.5 s away")
    options = SuiteOptions(reply_timeout_s=0.6, silence_s=0.2)
    try:
        report = run_checks(link, "far", options, select_checks(["set-mgmp", "set-sdk"]))
    finally:
        link.close()
    assert [(result.outcome, result.message) for result in report.results] == [
        (Outcome.PASSED, ""),
        (Outcome.PASSED, ""),
    ]


def test_the_checks_that_set_a_calibration_wait_for_a_distant_controller_to_take_it() -> None:
    # They wait for the reply to a #qd! sent after the settings (not for a silence), and that
    # reply, 200 ms late, must be read there, not taken for a reply to the depth query. (A
    # silence of 50 ms: a wait that ended on it would leave the reply to the next exchange.)
    link = PortLink(FaultyController(NO_FAULT, late_s=0.2), "200 ms away")
    names = [
        "calibration-range-ends-taken",
        "calibration-out-of-range-not-clamped",
        "overlong-frame-dropped",
        "longest-frame-accepted",
    ]
    options = SuiteOptions(reply_timeout_s=0.3, silence_s=0.05)
    try:
        report = run_checks(link, "far", options, select_checks(names))
    finally:
        link.close()
    assert len(report.results) == len(names)
    assert [(result.name, result.message) for result in report.failures] == []


class _WriteLog:
    """A link that keeps every write, in order."""

    def __init__(self, link: PortLink) -> None:
        self.description = link.description
        self._link = link
        self.writes: list[bytes] = []

    def read_available(self, timeout_s: float) -> bytes:
        return self._link.read_available(timeout_s)

    def write(self, data: bytes) -> None:
        self.writes.append(data)
        self._link.write(data)

    def wake(self) -> None:
        self._link.wake()

    def close(self) -> None:
        self._link.close()


def test_the_set_checks_send_each_command_with_the_motors_locked() -> None:
    # The set- checks no longer send a #stop! of their own: the runner's restore before each
    # check sends one, and nothing unlocks between it and the command checked.
    link = _WriteLog(PortLink(FaultyController(NO_FAULT), "locked"))
    try:
        report = run_checks(link, "locked", SuiteOptions(), select_checks(["set-"]))
    finally:
        link.close()
    assert report.passed
    locked = False
    checked = 0
    for data in link.writes:
        for frame in re.findall(rb"#[^#!]*!", data):
            if frame in (b"#stop!", b"#crcoff!"):
                locked = locked or frame == b"#stop!"
            elif frame == b"#start!":
                locked = False
            elif frame.startswith((b"#th.", b"#mvs.", b"#mvd.", b"#h+", b"#h-")):
                assert locked, f"{frame!r} was sent unlocked"
                checked += 1
    assert checked >= 5


def test_the_raw_reading_the_frame_length_checks_start_from_is_asked_as_any_query() -> None:
    # Before, these checks read "no $qr reply", whatever came: a late $qr (then left to land in
    # the next exchange, "an over-long #sdz, but the controller answered $qr…") or another
    # reply ("$qd.20!"). They now say what they expected and what came, as the query checks.
    # (0.3 s late: read in the 0.6 s the late reply is watched for, with room for a busy CPU)
    link = PortLink(FaultyController(NO_FAULT, late_s=0.3), "late")
    options = SuiteOptions(reply_timeout_s=0.2)
    names = ["overlong-frame-dropped", "longest-frame-accepted"]
    try:
        report = run_checks(link, "late", options, select_checks(names))
    finally:
        link.close()
    assert [result.name for result in report.results] == names
    for result in report.results:
        assert result.outcome is Outcome.FAILED
        assert result.message.startswith("expected $qr; no reply within 200 ms; $qr came late")


# Real-time motion (each watches the depth for seconds): on the newest Python only, as slow.
@pytest.mark.slow
@pytest.mark.integration
@pytest.mark.parametrize(
    ("fault", "name"),
    [("no-watchdog", "motion-link-loss-failsafe"), (NO_FAULT, "motion-locked-after-stop")],
)
def test_a_vehicle_that_cannot_dive_fails_the_no_dive_checks(fault: str, name: str) -> None:
    # Out of the water, or too buoyant for --motion-power, the vehicle dives for nothing.
    # Before, the checks that pass when it does not dive passed: a controller without a
    # link-loss failsafe passed motion-link-loss-failsafe run on the bench.
    controller = FaultyController(fault)
    with controller._inner.lock:
        controller._inner.robot.set_net_buoyancy(200.0)  # newtons up: far beyond the thrust
    link = PortLink(controller, fault)
    try:
        report = run_checks(
            link, fault, SuiteOptions(motion=True), select_checks([name], motion=True)
        )
    finally:
        link.close()
    (result,) = report.results
    assert result.outcome is Outcome.FAILED, result
    assert "could not be seen (is the vehicle in water" in result.message


def test_a_missing_reply_is_said_in_words_not_as_bytes() -> None:
    # A controller that switches its checksum mode only after the whole chunk drops the
    # checksummed #qd of #crcon!#qd<CS>!: nothing comes. Before, the failure read
    # "got b'nothing'", the word shown as if those bytes had come.
    fault = "mode-per-chunk"
    link = PortLink(FaultyController(fault), fault)
    try:
        report = run_checks(link, fault, SuiteOptions(), select_checks(["checksum-on-next-frame"]))
    finally:
        link.close()
    (result,) = report.results
    assert result.outcome is Outcome.FAILED
    assert result.message.endswith(", got nothing"), result.message


class _TextForQd(FaultyController):
    """Answers #qd! with an error line, not a frame (a firmware that knows no qd)."""

    def _outgoing(self, reply: bytes, sent: bytes, checksum: bool) -> bytes:
        reply = super()._outgoing(reply, sent, checksum)
        return reply.replace(b"$qd.0!", b"E02 unknown command\r\n") if sent == b"#qd!" else reply


def test_a_failure_for_want_of_a_frame_says_what_came_instead() -> None:
    # Before: "expected $qd; no reply within 250 ms", as if the line had stayed silent; only
    # the evidence below showed the controller's line.
    link = PortLink(_TextForQd(NO_FAULT), "text for qd")
    try:
        report = run_checks(link, "fake", SuiteOptions(), select_checks(["query-qd"]))
    finally:
        link.close()
    (result,) = report.results
    assert result.outcome is Outcome.FAILED
    assert result.message == (
        "expected $qd; no reply within 250 ms, but text came: b'E02 unknown command\\r\\n'"
    )


class _Echoes(FaultyController):
    """Writes back every byte it gets before its replies (a firmware with its UART's echo on)."""

    def _outgoing(self, reply: bytes, sent: bytes, checksum: bool) -> bytes:
        return sent + super()._outgoing(reply, sent, checksum)


def test_a_controller_that_echoes_fails_the_checks_and_the_run_ends_with_its_report() -> None:
    # Before: the echoed #qr! was taken for a $qr reply without a value, and the run ended in
    # an IndexError traceback at longest-frame-accepted, with no table and no JUnit file.
    link = PortLink(_Echoes(NO_FAULT), "echoes")
    try:
        report = run_checks(
            link,
            "echoes",
            SuiteOptions(),
            select_checks(["query-qd", "longest-frame-accepted", "calibration-applies"]),
        )
    finally:
        link.close()
    outcomes = {result.name: result.outcome for result in report.results}
    assert outcomes == {
        "query-qd": Outcome.FAILED,
        "longest-frame-accepted": Outcome.FAILED,
        "calibration-applies": Outcome.FAILED,
    }, report.results
    # The command that came back is named as a command, not as a second $qd.
    assert report.results[0].message == "expected $qd; got #qd! $qd", report.results[0].message


class _BannerThenSilent(FaultyController):
    """Writes a boot banner and then never answers (a firmware whose parser never runs)."""

    def __init__(self) -> None:
        super().__init__(NO_FAULT)
        self._output += b"BOOT v1.2\r\n"

    def _outgoing(self, reply: bytes, sent: bytes, checksum: bool) -> bytes:
        return b""


def test_a_controller_that_does_not_answer_is_shown_with_what_it_did_write() -> None:
    # Before: "did not answer #q.l! within 0.5 s (received b'')": the banner was read by the
    # restore sent before each #q.l! and thrown away, and the line looked dead.
    link = PortLink(_BannerThenSilent(), "banner")
    try:
        with pytest.raises(PreflightError, match=r"\(received b'BOOT v1\.2\\r\\n'\)"):
            run_checks(link, "banner", SuiteOptions(boot_timeout_s=0.5))
    finally:
        link.close()


class _AtNineSixHundredBaud(FaultyController):
    """The simulated controller behind a 9600-baud line: the host's bytes reach it at 960 a
    second, after those written before them (the serial driver holds what the line has not
    sent yet, and write() returns at once)."""

    BAUD = 9600

    def __init__(self) -> None:
        super().__init__(NO_FAULT)
        self._line: queue.Queue[tuple[float, bytes] | None] = queue.Queue()
        self._line_free_s = 0.0
        self._carrier = threading.Thread(target=self._carry, daemon=True)
        self._carrier.start()

    def write(self, data: bytes) -> int:
        on_line_s = len(data) * 10 / self.BAUD  # (8N1: ten bits a byte)
        self._line_free_s = max(time.monotonic(), self._line_free_s) + on_line_s
        self._line.put((self._line_free_s, bytes(data)))
        return len(data)

    def close(self) -> None:
        self._line.put(None)  # (what was written before the close still crosses the line)
        self._carrier.join()
        super().close()

    def _carry(self) -> None:
        while (item := self._line.get()) is not None:
            arrives_s, data = item
            time.sleep(max(arrives_s - time.monotonic(), 0.0))  # (the line's own time)
            super().write(data)


def test_a_long_write_on_a_slow_line_is_waited_for_before_its_query_is() -> None:
    # garbage-survived writes 602 bytes, 0.63 s on a 9600-baud line, then a #qd! that waits
    # behind them. Before, the reply waits counted from the end of write(), and a controller
    # that answers at once failed: "$qd came late, about 540 ms after the query".
    link = PortLink(_AtNineSixHundredBaud(), "9600 baud")
    options = SuiteOptions(baudrate=_AtNineSixHundredBaud.BAUD)
    try:
        report = run_checks(link, "9600 baud", options, select_checks(["garbage-survived"]))
    finally:
        link.close()
    (result,) = report.results
    assert result.outcome is Outcome.PASSED, result.message


class _ChecksumsAlways(FaultyController):
    """Puts a checksum on every reply, in plain mode too (P3: a reply carries one only in
    checksum mode)."""

    def _outgoing(self, reply: bytes, sent: bytes, checksum: bool) -> bytes:
        reply = super()._outgoing(reply, sent, checksum)
        if checksum:
            return reply
        crc8 = get_algorithm("crc8")
        return re.sub(rb"\$([^!$]*)!", lambda m: b"$" + m[1] + crc8.digits(m[1]) + b"!", reply)


def test_a_preflight_answer_the_decoder_refuses_is_named_with_why() -> None:
    # Before: "did not answer #q.l! within 0.5 s (received b'$q.l.021!…')", and the reader was
    # left to see that each answer came, with a checksum the plain mode does not have.
    link = PortLink(_ChecksumsAlways(NO_FAULT), "checksums always")
    try:
        with pytest.raises(PreflightError, match=r"b'\$q\.l\.021!' is no valid frame: "):
            run_checks(link, "checksums always", SuiteOptions(boot_timeout_s=0.5))
    finally:
        link.close()


class _NeverUnlocks(FaultyController):
    """Takes #start! for nothing: its motors stay locked (P7)."""

    def _incoming(self, data: bytes) -> bytes:
        return super()._incoming(data).replace(b"#start!", b"")


@pytest.mark.slow
@pytest.mark.integration
def test_a_controller_that_never_unlocks_is_named_as_a_cause_with_the_water() -> None:
    # Before: "… (is the vehicle in water?)" alone, for every motion check, where the firmware
    # engineer's bug was #start!.
    link = PortLink(_NeverUnlocks(NO_FAULT), "never unlocks")
    checks = select_checks(["motion-stop-halts", "motion-out-of-range-not-clamped"], motion=True)
    try:
        report = run_checks(link, "never unlocks", SuiteOptions(motion=True), checks)
    finally:
        link.close()
    for result in report.results:
        assert result.outcome is Outcome.FAILED, result
        assert "unlock the motors on #start!?" in result.message, result.message


def test_a_controller_whose_failsafe_cannot_be_seen_leaves_stop_unverified_and_says_so(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # Without a link-loss failsafe (P17 allows a watchdog of 0) nothing without motion shows
    # the lock: stop-locks is skipped, not passed, and the summary says #stop! went unverified.
    from rovlink.cli.check import _print_report

    fault = "no-watchdog"
    link = PortLink(FaultyController(fault), fault)
    try:
        report = run_checks(link, fault, SuiteOptions(), select_checks(["stop-locks"]))
    finally:
        link.close()
    (result,) = report.results
    assert result.outcome is Outcome.SKIPPED, result
    assert result.message.startswith("#stop! not verified without --motion: "), result.message
    _print_report(report)
    out = " ".join(capsys.readouterr().out.split())
    assert "skip stop-locks: #stop! not verified without --motion: unlocked at zero " in out
    assert "no other check without --motion shows that #stop! locks the motors" in out
    assert "0 of 1 checks passed" in out
    assert out.rstrip().endswith("; #stop! NOT verified"), out


def test_the_summary_of_a_run_whose_stop_check_passed_does_not_call_stop_unverified(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from rovlink.cli.check import _print_report
    from rovlink.conformance import CheckResult

    passed = CheckResult("stop-locks", ("P7",), "d", Outcome.PASSED)
    _print_report(Report("sim://", [passed]))
    assert "not verified" not in capsys.readouterr().out.replace("\n", " ")
