"""Ctrl-C cancels an asyncio command, wherever it lands, on every supported Python.

Each case runs in a process of its own (a signal handler is process-wide) on an event loop that
raises SIGINT at the worst moment the test can choose: while a future wakes the task awaiting
it. Python 3.10's ``asyncio.run`` raised KeyboardInterrupt there; the waiting task was never
woken, and the run's shutdown waited for it for ever.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

#: The script's own wait is milliseconds; this bounds a hang.
PROCESS_TIMEOUT_S = 30.0

SCRIPT = textwrap.dedent(
    """
    import asyncio
    import signal
    import sys

    from rovlink.cli import _take_termination_as_ctrl_c, async_run

    runner, scenario = sys.argv[1:]
    SIGNAL = signal.SIGINT
    if scenario == "sigterm-in-a-background-job":
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a shell starts a job with &
        _take_termination_as_ctrl_c()  # as the command line does
        SIGNAL = signal.SIGTERM

    class InterruptedWhileWaking(asyncio.SelectorEventLoop):
        armed = False

        def call_soon(self, callback, *args, context=None):
            # A future schedules its done-callbacks (a task's wake-up) as call_soon(cb, future).
            if self.armed and args and isinstance(args[0], asyncio.Future):
                self.armed = False
                signal.raise_signal(SIGNAL)
            return super().call_soon(callback, *args, context=context)

    class Policy(asyncio.DefaultEventLoopPolicy):
        _loop_factory = InterruptedWhileWaking

    asyncio.set_event_loop_policy(Policy())
    ended = []

    async def sleeper(future):
        try:
            await future
            await asyncio.sleep(60)
        finally:
            ended.append("sleeper")

    async def main():
        loop = asyncio.get_running_loop()
        if scenario == "sigterm-on-the-way-out":
            loop.call_soon(signal.raise_signal, signal.SIGINT)
            try:
                await asyncio.sleep(60)
            finally:
                signal.raise_signal(signal.SIGTERM)  # a terminal closed as the command ends
                await asyncio.sleep(0.05)  # the way out awaits (#stop!)
                ended.append("main")
        if scenario == "ctrl-c-in-the-last-step":
            ended.append("main")
            signal.raise_signal(SIGNAL)  # and the task ends without another await
            return
        future = loop.create_future()
        task = asyncio.ensure_future(sleeper(future))
        await asyncio.sleep(0)  # the sleeper awaits the future
        try:
            loop.armed = True
            future.set_result(None)  # the signal comes as it wakes the sleeper
            await asyncio.sleep(60)
        finally:
            await asyncio.sleep(0)  # a command's way out awaits (#stop!, a close)
            ended.append("main")

    try:
        getattr(async_run, runner)(main())
    except KeyboardInterrupt:
        print("interrupted", *sorted(ended))
    else:
        print("not interrupted", *sorted(ended))
    """
)


def _run(runner: str, scenario: str) -> list[str]:
    source = str(Path(__file__).resolve().parents[2] / "src")
    completed = subprocess.run(
        [sys.executable, "-c", SCRIPT, runner, scenario],
        capture_output=True,
        text=True,
        timeout=PROCESS_TIMEOUT_S,
        env={"PYTHONPATH": source, "PATH": ""},
        check=False,
    )
    assert completed.returncode == 0, completed.stderr
    return completed.stdout.splitlines()


@pytest.mark.parametrize("runner", ["run_async", "run_cancelled_by_ctrl_c"])
def test_ctrl_c_while_a_future_wakes_a_task_cancels_the_command_cleanly(runner: str) -> None:
    # Both ways out ran to their end: the main task's, after an await, and the woken task's.
    assert _run(runner, "ctrl-c-while-waking") == ["interrupted main sleeper"]


def test_sigterm_to_a_background_job_cancels_the_command_cleanly() -> None:
    # A background job ignores SIGINT: SIGTERM (or SIGHUP) must cancel the command itself
    # rather than raise KeyboardInterrupt inside the event loop (before, it hung there).
    assert _run("run_async", "sigterm-in-a-background-job") == ["interrupted main sleeper"]


@pytest.mark.parametrize("runner", ["run_async", "run_cancelled_by_ctrl_c"])
def test_ctrl_c_as_the_command_takes_its_last_step_still_interrupts(runner: str) -> None:
    # Too late to cancel the task, not too late to say the command was interrupted (exit 130).
    assert _run(runner, "ctrl-c-in-the-last-step") == ["interrupted main"]


def test_sigterm_on_the_way_out_of_a_ctrl_c_does_not_cut_it_short() -> None:
    # Before, the second cancellation came in the middle of the way out: no #stop!.
    assert _run("run_async", "sigterm-on-the-way-out") == ["interrupted main"]
