"""``rovlink demo``: the scripted dive runs through the driver and locks the robot at the end."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

import rovlink
from rovlink.cli.demo import DivePlan, DiveProgress, run_dive
from rovlink.client.events import BytesSent
from rovlink.recorder import FrameEntry, read_entries
from tests.cli.conftest import RunCli
from tests.client.conftest import CONDITION_TIMEOUT_S, REPLY_TIMEOUT_S, WatchedLock, wait_until


def _fast_sim_url(tmp_path: Path) -> str:
    # As fast as the CPU allows: the watchdog counts simulated seconds, which pass far faster
    # than the demo's wall-clock polling, so it is off here.
    config = tmp_path / "fast.toml"
    config.write_text("[controller]\nwatchdog_s = 0\n")
    return f"sim://?realtime=0&seed=1&config={config}"


def test_the_dive_reaches_each_depth_and_ends_locked(tmp_path: Path) -> None:
    seen: list[str] = []

    def record(progress: DiveProgress) -> None:
        running = [step.name for step in progress.steps if step.status == "running"]
        if running and (not seen or seen[-1] != running[0]):
            seen.append(running[0])

    plan = DivePlan(depth_cm=60, hold_s=0.1, leg_s=0.1, reach_timeout_s=20)
    with rovlink.connect(_fast_sim_url(tmp_path), keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        progress = run_dive(rov, plan, record)
        port = rov._link.port  # type: ignore[attr-defined]
        with port.lock:
            state = port.controller.state()
    assert [step.status for step in progress.steps] == ["done"] * len(progress.steps)
    assert seen[0] == "unlock"
    assert seen[-1] == "lock"
    assert len(seen) == len(progress.steps)
    assert state.locked
    assert progress.steps[1].detail.startswith("at ")


def test_a_failing_dive_still_stops_the_robot(tmp_path: Path) -> None:
    def explode(progress: DiveProgress) -> None:
        if progress.steps[3].status == "running":
            raise RuntimeError("display failed")

    with rovlink.connect(_fast_sim_url(tmp_path), keepalive=None, timeout=REPLY_TIMEOUT_S) as rov:
        with pytest.raises(RuntimeError, match="display failed"):
            run_dive(rov, DivePlan(depth_cm=20, hold_s=0, leg_s=0.1), explode)
        port = rov._link.port  # type: ignore[attr-defined]
        with port.lock:
            state = port.controller.state()
    assert state.locked
    assert state.power_percent == 0


def test_demo_command(tmp_path: Path, run_cli: RunCli) -> None:
    # "0 timeouts" is checked below: every reply is expected, so the timeout is a long one.
    result = run_cli(
        "demo",
        _fast_sim_url(tmp_path),
        "--depth",
        "50",
        "--hold",
        "0.1",
        "--leg",
        "0.1",
        "--reach-timeout",
        "20",
        "--timeout",
        str(REPLY_TIMEOUT_S),
    )
    assert result.status == 0, result.err
    for text in (
        "unlock",
        "dive to 50 cm",
        "square: left",
        "read every sensor",
        "surface",
        "lock",
        "#th.270.30!",
        "motors off and locked",
        "0 timeouts",
    ):
        assert text in result.out


def test_demo_that_cannot_reach_its_depth_fails(tmp_path: Path, run_cli: RunCli) -> None:
    result = run_cli(
        "demo",
        _fast_sim_url(tmp_path),
        "--depth",
        "9000",
        "--hold",
        "0",
        "--leg",
        "0",
        "--reach-timeout",
        "0.3",
    )
    assert result.status == 1
    assert "not completed: dive to 9000 cm" in result.err


def test_demo_options_are_checked(run_cli: RunCli) -> None:
    result = run_cli("demo", "--power", "150")
    assert result.status == 2
    assert "argument --power: 150 is not in 0–100" in result.err


def test_a_dive_that_misses_its_depth_never_moves_horizontally(tmp_path: Path) -> None:
    plan = DivePlan(depth_cm=9000, hold_s=0, leg_s=0, reach_timeout_s=0.3)
    with rovlink.connect(_fast_sim_url(tmp_path), keepalive=None) as rov:
        progress = run_dive(rov, plan, lambda progress: None)
        port = rov._link.port  # type: ignore[attr-defined]
        with port.lock:
            state = port.controller.state()
    statuses = [step.status for step in progress.steps]
    assert statuses[1] == "not reached"
    assert statuses[2:8] == ["skipped"] * 6  # hold, the square, the readings
    assert statuses[9] == "done"
    assert state.locked
    assert state.power_percent == 0


def test_a_bad_url_leaves_no_recording(run_cli: RunCli, tmp_path: Path) -> None:
    recording = tmp_path / "badurl.mcap"
    result = run_cli("demo", "sim://?speed=3", "--record", str(recording))
    assert result.status == 2
    assert "unknown sim option 'speed'" in result.err
    assert not recording.exists()


def test_a_leak_during_the_dive_aborts_it_with_stop(tmp_path: Path) -> None:
    # Before, the dive went on through a leak: held its depth, drove its square at 30 %,
    # and ended with status 0 (as tune and the motion checks do, a leak now ends it).
    sent: list[bytes] = []
    plan = DivePlan(depth_cm=60, hold_s=0.1, leg_s=0.1, reach_timeout_s=20)

    def on_event(event: object) -> None:
        if isinstance(event, BytesSent):
            sent.append(event.data)

    with rovlink.connect(
        _fast_sim_url(tmp_path), keepalive=None, timeout=REPLY_TIMEOUT_S, on_event=on_event
    ) as rov:
        port = rov._link.port  # type: ignore[attr-defined]

        def leak_on_the_way_down(progress: DiveProgress) -> None:
            if progress.steps[1].status == "running" and progress.latest is not None:
                with port.lock:  # the probe wet from now on (a pulse is latched)
                    port.robot.inject_leak(duration_s=1000.0)

        progress = run_dive(rov, plan, leak_on_the_way_down)
        with port.lock:
            state = port.controller.state()
    statuses = [step.status for step in progress.steps]
    assert statuses[:3] == ["done", "aborted", "skipped"]
    assert statuses[3:7] == ["skipped"] * 4  # the square
    assert progress.aborted is not None
    assert "the leak sensor fired (q.l = 1) during 'dive to 60 cm'" in progress.aborted
    assert not any(data.startswith(b"#th.") for data in sent)  # no square
    assert state.locked
    assert sent.index(b"#stop!") > sent.index(b"#start!")


def test_a_leak_latched_before_the_dive_starts_nothing(tmp_path: Path, run_cli: RunCli) -> None:
    recording = tmp_path / "leaking.jsonl"
    url = f"{_fast_sim_url(tmp_path)}&leak_at=0"
    result = run_cli("demo", url, "--hold", "0", "--record", str(recording))
    assert result.status == 1
    assert (
        "rovlink demo: the leak sensor had fired before the dive (q.l = 1): look at the "
        "vehicle, then reset the latch (slreset); the dive was not started"
    ) in result.err.splitlines()
    sent = [
        entry.name
        for entry in read_entries(str(recording))
        if isinstance(entry, FrameEntry) and entry.direction == "out"
    ]
    assert "q.l" in sent
    assert not {"start", "mvd", "th"} & set(sent)


def test_a_stop_from_another_thread_ends_the_dive_without_sending_what_it_superseded(
    tmp_path: Path,
) -> None:
    # A program's safety thread calls stop() while the dive's move waits to be written (behind
    # another write): the driver does not send the move (SupersededByStopError). Before, that
    # error left run_dive as if the link had failed, and the progress said nothing of it; now
    # the dive ends as stopped, and nothing of the dive follows the #stop!.
    sent: list[bytes] = []
    plan = DivePlan(depth_cm=60, hold_s=0.1, leg_s=0.1, reach_timeout_s=20)

    def on_event(event: object) -> None:
        if isinstance(event, BytesSent):
            sent.append(event.data)

    with rovlink.connect(
        _fast_sim_url(tmp_path), keepalive=None, timeout=REPLY_TIMEOUT_S, on_event=on_event
    ) as rov:
        port = rov._link.port  # type: ignore[attr-defined]
        wire = WatchedLock(rov._wire_lock)
        rov._wire_lock = wire  # type: ignore[assignment]
        held = threading.Event()
        safety: list[threading.Thread] = []

        def slow_write_then_stop() -> None:
            with wire:  # another thread's write that the line is slow to take
                held.set()
                assert wait_until(lambda: wire.waiting == 1)  # the dive's move waits
                stopping = threading.Thread(target=rov.stop)  # the safety thread
                stopping.start()
                safety.append(stopping)
                assert wait_until(lambda: wire.waiting == 2)

        def stop_at_the_square(progress: DiveProgress) -> None:
            if progress.steps[3].status == "running" and not held.is_set():
                threading.Thread(target=slow_write_then_stop, daemon=True).start()
                assert held.wait(CONDITION_TIMEOUT_S)

        progress = run_dive(rov, plan, stop_at_the_square)
        for thread in safety:
            thread.join(CONDITION_TIMEOUT_S)
        with port.lock:
            state = port.controller.state()
    statuses = [step.status for step in progress.steps]
    assert statuses[:4] == ["done", "done", "done", "aborted"]
    assert statuses[4:9] == ["skipped"] * 5
    assert progress.steps[9].status == "done"
    assert progress.steps[9].detail == "motors off and locked: stop() called"
    assert progress.aborted == (
        "stop() was called during 'square: ahead': the dive was aborted (#th.0.30! not sent)"
    )
    assert b"#th.0.30!" not in sent  # the superseded move was not retried
    first_stop = sent.index(b"#stop!")
    assert all(data in (b"#stop!", b"#qsa!") for data in sent[first_stop:])
    assert state.locked
