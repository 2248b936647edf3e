"""Settings for the whole suite."""

from __future__ import annotations

import os
import signal

import pytest
from hypothesis import settings

# Many tests end a command with Ctrl-C (SIGINT) as a user does. A shell starts a background job
# (`pytest &`, or two suites at once) with SIGINT ignored, every process it starts inherits that,
# and rovlink keeps a signal ignored on entry (as `nohup` asks): those tests would then wait for an
# exit that never comes. Python's own handler here makes each command start with the default.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

# Property tests check results, not speed: on a loaded machine one example can take longer than
# Hypothesis's default deadline of 200 ms, which would fail the run through no fault of the code.
settings.register_profile("rovlink", deadline=None)
settings.load_profile("rovlink")


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """In CI (ROVLINK_FAIL_ON_SKIP=1) a skipped test fails the run: a missing tool is a broken
    machine, not a pass."""
    if os.environ.get("ROVLINK_FAIL_ON_SKIP") != "1" or exitstatus != 0:
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    skipped = reporter.stats.get("skipped", []) if reporter is not None else []
    if skipped:
        reasons = sorted(
            {
                str(report.longrepr[-1])
                if isinstance(report.longrepr, tuple)
                else str(report.longrepr)
                for report in skipped
            }
        )
        print(f"\n{len(skipped)} test(s) skipped in CI: " + "; ".join(reasons))
        session.exitstatus = 1
