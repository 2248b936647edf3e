"""The controller's TCP line (shared by ``rovlink sim`` and ``rovlink controller``), stepped on
the test's own thread: a selector turn happens only when the test calls ``wait``."""

from __future__ import annotations

import errno
import logging
import os
import socket
import struct
import time
from typing import Any

import pytest

from rovlink.controller import lines as lines_module
from rovlink.controller.lines import Line, Lines, TcpLine

pytestmark = pytest.mark.integration


def _reset_connection(address: tuple[str, int]) -> None:
    """Connect, then abort the connection (a zero linger: the close sends a reset)."""
    client = socket.create_connection(address, timeout=5)
    client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    client.close()


def test_a_client_that_resets_before_it_is_accepted_does_not_end_the_server() -> None:
    # A port scan, or a client killed as it connects: the connection is reset while it waits in
    # the listener's queue. Before, asking its peer's address raised ENOTCONN out of the
    # server's loop, and `rovlink sim` (or a robot's `rovlink controller`) ended with a
    # traceback.
    received: list[bytes] = []
    lines = Lines(lambda line, data: received.append(data), busy_message=b"busy\r\n")
    try:
        address = lines.listen_tcp("127.0.0.1", 0)
        _reset_connection(address)
        lines.wait(1.0)  # accepts the reset connection
        assert not any(isinstance(line, TcpLine) for line in lines.lines)
        with socket.create_connection(address, timeout=5) as client:
            client.sendall(b"#qd!")
            for _ in range(100):  # turns of the loop until the bytes are read
                if received:
                    break
                lines.wait(0.05)
            assert received == [b"#qd!"]
    finally:
        lines.close()


def test_lines_open_only_for_clients_that_are_still_connected() -> None:
    opened: list[Line] = []
    lines = Lines(lambda line, data: None, busy_message=b"busy\r\n", on_open=opened.append)
    try:
        _reset_connection(lines.listen_tcp("127.0.0.1", 0))
        lines.wait(1.0)
        assert opened == []
    finally:
        lines.close()


def test_a_reset_connection_does_not_push_out_a_silent_client() -> None:
    # A silent client gives way to a new one (its link may have died unseen), but not to one
    # that has gone already.
    lines = Lines(lambda line, data: None, busy_message=b"busy\r\n", silent_client_gives_way_s=1e-6)
    try:
        address = lines.listen_tcp("127.0.0.1", 0)
        with socket.create_connection(address, timeout=5):
            lines.wait(1.0)
            (served,) = lines.lines
            _reset_connection(address)
            lines.wait(1.0)
            assert lines.lines == [served]
    finally:
        lines.close()


def test_out_of_file_descriptors_pauses_accepting_and_keeps_serving_the_line(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    # A process out of descriptors fails accept(2) with EMFILE and leaves the connection in the
    # listener's queue, so the listener stays readable. Before, the error ended the loop (or,
    # caught, made it spin at 100 % CPU). Now the listener rests, the connected line is served
    # (a #stop! goes through), the error is logged once, and accepting resumes.
    monkeypatch.setattr(lines_module, "ACCEPT_PAUSE_S", 0.05, raising=False)
    received: list[bytes] = []
    lines = Lines(lambda line, data: received.append(data), busy_message=b"busy\r\n")
    real_accept = socket.socket.accept
    failing = {"on": False, "calls": 0}

    def accept(self: socket.socket) -> tuple[socket.socket, Any]:
        if failing["on"]:
            failing["calls"] += 1
            raise OSError(errno.EMFILE, os.strerror(errno.EMFILE))
        return real_accept(self)

    monkeypatch.setattr(socket.socket, "accept", accept)
    try:
        address = lines.listen_tcp("127.0.0.1", 0)
        with socket.create_connection(address, timeout=5) as served:
            lines.wait(1.0)
            assert [type(line) for line in lines.lines] == [TcpLine]
            failing["on"] = True
            with caplog.at_level(logging.WARNING, logger="rovlink"):
                waiting = socket.create_connection(address, timeout=5)
                started_s = time.monotonic()
                turns = 0
                while failing["calls"] < 3 and time.monotonic() - started_s < 10:
                    lines.wait(0.01)
                    turns += 1
                served.sendall(b"#stop!")
                for _ in range(100):
                    if received:
                        break
                    lines.wait(0.01)
            assert received == [b"#stop!"]
            # Tried again once a pause, not on every turn of the loop.
            assert failing["calls"] == 3
            assert turns >= 3
            errors = [r for r in caplog.records if "cannot accept" in r.getMessage()]
            assert len(errors) == 1
            assert "Too many open files" in errors[0].getMessage()
            assert "ulimit -n" in errors[0].getMessage()
            failing["on"] = False
        # The served client has gone: the one that waited in the queue is served now.
        waiting_name = "tcp client {}:{}".format(*waiting.getsockname()[:2])
        for _ in range(500):
            if [line.name for line in lines.lines] == [waiting_name]:
                break
            lines.wait(0.01)
        assert [line.name for line in lines.lines] == [waiting_name]
        assert any("accepting connections again" in r.getMessage() for r in caplog.records)
        waiting.close()
    finally:
        lines.close()
