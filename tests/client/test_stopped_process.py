"""A query's deadline is absolute: a process that is stopped and continued again and again
(SIGSTOP/SIGCONT from a job control shell, a sampling profiler's ptrace) still times its queries
out on time. A read asleep in ``recv`` with the kernel's receive timeout restarted the whole
timeout after each stop, so such a query never ended."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from tests.rovlink_process import rovlink_environment

pytestmark = pytest.mark.integration

#: A program that asks a controller which never answers (the far end of a socket pair), with
#: one attempt of 0.4 s, and prints how long the query took to fail.
_SILENT_CONTROLLER_QUERY = """
import socket, sys, time
from rovlink.client import Client, ClientOptions, QueryTimeoutError
from rovlink.client.links import SocketLink
ours, theirs = socket.socketpair()
options = ClientOptions(timeout_s=0.4, retries=0, keepalive_s=None, boot_timeout_s=None,
                        motion_timeout_s=None)
client = Client(SocketLink(ours, "socket pair"), options)
print("ready", flush=True)
started = time.monotonic()
try:
    client.depth_cm()
except QueryTimeoutError:
    print(f"timed out after {time.monotonic() - started:.3f}", flush=True)
"""
_GIVE_UP_S = 3.0


def test_a_query_times_out_on_time_in_a_process_stopped_and_continued_again_and_again() -> None:
    child = subprocess.Popen(
        [sys.executable, "-c", _SILENT_CONTROLLER_QUERY],
        stdout=subprocess.PIPE,
        text=True,
        env=rovlink_environment(),
    )
    try:
        assert child.stdout is not None
        assert child.stdout.readline() == "ready\n"
        # Stopped for 10 ms every 50 ms: it runs most of the time, and its deadline passes.
        give_up_at = time.monotonic() + _GIVE_UP_S
        while child.poll() is None and time.monotonic() < give_up_at:
            os.kill(child.pid, signal.SIGSTOP)
            time.sleep(0.01)
            os.kill(child.pid, signal.SIGCONT)
            time.sleep(0.04)
        assert child.poll() is not None, f"the query did not end within {_GIVE_UP_S} s"
        line = child.stdout.readline()
        assert line.startswith("timed out after "), line
        # 0.4 s and the stops, not a wait restarted after each of them (which never ended).
        assert float(line.split()[-1]) < _GIVE_UP_S
    finally:
        child.kill()
        child.wait()
