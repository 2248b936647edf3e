"""The simulated controller on a real pseudo-terminal and a real TCP socket."""

from __future__ import annotations

import contextlib
import os
import select
import socket
import struct
import time
from collections.abc import Callable

import pytest
import serial

from rovlink.busy_tcp import RefusedClients
from rovlink.controller import ControllerConfig
from rovlink.controller import lines as lines_module
from rovlink.controller.lines import Lines, TcpLine
from rovlink.sim import SimConfig
from rovlink.sim.server import BUSY_MESSAGE, LINE_BUFFER_BYTES, SimServer, parse_tcp_address
from tests.client.conftest import wait_until
from tests.sim.conftest import StartServer

pytestmark = pytest.mark.integration


def _read_frames(read: Callable[[], bytes], count: int, timeout_s: float = 5.0) -> bytes:
    """Read until ``count`` frame ends have arrived."""
    data = b""
    deadline = time.monotonic() + timeout_s
    while data.count(b"!") < count:
        if time.monotonic() > deadline:
            pytest.fail(f"timed out with {data!r}")
        data += read()
    return data


def _open_pty(server: SimServer) -> serial.Serial:
    assert server.pty_path is not None
    return serial.Serial(server.pty_path, 115200, timeout=0.05)


def _reader(port: serial.Serial) -> Callable[[], bytes]:
    return lambda: port.read(256)  # waits up to the port's timeout


def _connect(server: SimServer) -> socket.socket:
    assert server.tcp_address is not None
    connection = socket.create_connection(server.tcp_address, timeout=5)
    connection.settimeout(0.05)
    return connection


def _recv(connection: socket.socket) -> Callable[[], bytes]:
    def read() -> bytes:
        try:
            return connection.recv(4096)
        except TimeoutError:
            return b""

    return read


def test_a_query_over_the_pty_gets_its_reply(start_server: StartServer) -> None:
    server = start_server(tcp=False)
    with _open_pty(server) as port:
        port.write(b"#qd!")
        assert _read_frames(_reader(port), 1) == b"$qd.0!"


def test_the_pty_is_raw_no_echo_no_line_translation(start_server: StartServer) -> None:
    server = start_server(tcp=False)
    with _open_pty(server) as port:
        port.write(b"#debug1!\r\n#qx!")
        data = b""
        deadline = time.monotonic() + 5
        while not data.endswith(b"\r\n") or b"unknown" not in data:
            assert time.monotonic() < deadline, data
            data += port.read(100)
        assert data == (
            b"debug: debug output on\r\ndebug: dropped <qx>: unknown: unknown command 'qx'\r\n"
        )


def test_a_query_over_tcp_gets_its_reply(start_server: StartServer) -> None:
    server = start_server(pty=False)
    with _connect(server) as connection:
        connection.sendall(b"#qsa!")
        reply = _read_frames(_recv(connection), 6)
        assert reply.startswith(b"$qd.0!$qr.20!$q.l.0!$qro.")


def test_mode_changes_in_one_write_apply_from_the_next_frame_over_tcp(
    start_server: StartServer,
) -> None:
    server = start_server(pty=False)
    with _connect(server) as connection:
        connection.sendall(b"#qd!#crcon!#qd8C!#crcoff!#qd!")
        assert _read_frames(_recv(connection), 3) == b"$qd.0!$qd.0A2!$qd.0!"


def test_mode_changes_in_one_write_apply_from_the_next_frame_over_the_pty(
    start_server: StartServer,
) -> None:
    server = start_server(tcp=False)
    with _open_pty(server) as port:
        port.write(b"#crcon!#qd8C!#crcoff!#qd!")
        assert _read_frames(_reader(port), 2) == b"$qd.0A2!$qd.0!"


def test_a_second_tcp_client_is_told_it_is_busy_and_closed(start_server: StartServer) -> None:
    server = start_server(pty=False)
    with _connect(server) as first:
        first.sendall(b"#qd!")
        _read_frames(_recv(first), 1)
        with _connect(server) as second:
            second.settimeout(5)
            received = b""
            while chunk := second.recv(4096):
                received += chunk
            assert received == BUSY_MESSAGE
        first.sendall(b"#qd!")  # the first client is undisturbed
        assert _read_frames(_recv(first), 1) == b"$qd.0!"


def test_a_tcp_client_whose_link_died_unseen_gives_way_to_a_new_one(
    start_server: StartServer,
) -> None:
    # A station on Wi-Fi that dropped: no FIN ever arrives, the connection stays open. Before,
    # the station connecting again read "busy" for as long as the simulator ran. Its motion
    # stops when its line goes (it drove).
    server = start_server(pty=False, silent_client_gives_way_s=0.2)
    with _connect(server) as dead:
        dead.sendall(b"#start!#th.90.50!#qd!")
        _read_frames(_recv(dead), 1)
        assert not server.robot.controller.locked

        def connected_again() -> bool:
            with _connect(server) as again:
                again.sendall(b"#qd!")
                try:
                    return _read_frames(_recv(again), 1, timeout_s=1.0).startswith(b"$qd.")
                except pytest.fail.Exception:
                    return False

        assert wait_until(connected_again, timeout_s=10.0)
        assert server.robot.controller.locked  # the line that drove went: stopped at once


def test_a_tcp_client_that_keeps_its_link_alive_is_not_pushed_out(
    start_server: StartServer,
) -> None:
    server = start_server(pty=False, silent_client_gives_way_s=0.5)
    with _connect(server) as live:
        for _ in range(5):  # queries faster than the silence that gives way
            live.sendall(b"#qd!")
            assert _read_frames(_recv(live), 1) == b"$qd.0!"
            with _connect(server) as other:
                other.settimeout(5)
                assert other.recv(4096).startswith(b"busy")


def test_a_silent_client_gives_way_after_three_seconds_or_the_failsafes_time() -> None:
    from rovlink.controller.lines import SILENT_CLIENT_GIVES_WAY_S

    def gives_way_s(server: SimServer) -> float:
        return server._lines._silent_client_gives_way_s

    assert gives_way_s(SimServer(seed=1)) == SILENT_CLIENT_GIVES_WAY_S
    slow = SimConfig(controller=ControllerConfig(watchdog_s=5.0))
    assert gives_way_s(SimServer(slow, seed=1)) == 5.0
    assert gives_way_s(SimServer(slow, seed=1, speed=10.0)) == SILENT_CLIENT_GIVES_WAY_S


def test_a_second_client_that_writes_at_once_still_reads_why_it_was_refused(
    start_server: StartServer,
) -> None:
    # A client's first probe is usually on its way before the server refuses it: closing a
    # socket with unread input resets the connection, and the reset can discard "busy".
    server = start_server(pty=False)
    with _connect(server) as first:
        first.sendall(b"#qd!")
        _read_frames(_recv(first), 1)
        for _ in range(5):
            with _connect(server) as second:
                second.sendall(b"#crcoff!#qd!" * 100)
                second.settimeout(5)
                received = b""
                while chunk := second.recv(4096):  # (a reset raises ConnectionResetError)
                    received += chunk
                assert received == BUSY_MESSAGE


def test_refused_clients_that_stay_connected_are_not_kept_without_bound(
    start_server: StartServer,
) -> None:
    # Each refused client is kept until it closes (or for a while), so that it reads "busy";
    # a flood of them must not run the server's selector out of descriptors.
    server = start_server(pty=False)
    extra = RefusedClients.MAX_KEPT + 12
    with _connect(server) as first, contextlib.ExitStack() as stack:
        first.sendall(b"#qd!")
        _read_frames(_recv(first), 1)
        for _ in range(extra):
            second = stack.enter_context(_connect(server))
            second.settimeout(5)
            assert second.recv(4096) == BUSY_MESSAGE  # (all of it: one small write)
        assert len(server._lines._refused) <= RefusedClients.MAX_KEPT
        first.sendall(b"#qd!")  # the client being served is undisturbed
        assert _read_frames(_recv(first), 1) == b"$qd.0!"


def test_after_the_client_leaves_the_next_one_is_served(start_server: StartServer) -> None:
    server = start_server(pty=False)
    with _connect(server) as first:
        first.sendall(b"#qd!")
        _read_frames(_recv(first), 1)
    deadline = time.monotonic() + 5
    while True:  # the server notices the disconnection on its next turn
        with _connect(server) as second:
            second.sendall(b"#qd!")
            reply = b""
            while time.monotonic() < deadline and not reply.endswith((b"!", b"\n")):
                reply += _recv(second)()
            if reply == b"$qd.0!":
                return
            assert reply == BUSY_MESSAGE
        assert time.monotonic() < deadline


def _count_pty_writes(monkeypatch: pytest.MonkeyPatch) -> list[bytes]:
    """Record every write the server makes to the PTY."""
    written: list[bytes] = []
    write = lines_module.PtyLine.write

    def counting_write(line: lines_module.PtyLine, data: bytes) -> int:
        written.append(data)
        return write(line, data)

    monkeypatch.setattr(lines_module.PtyLine, "write", counting_write)
    return written


def _nothing_readable(path: str) -> bool:
    """Whether the terminal side of the PTY has no byte waiting."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    try:
        os.read(fd, 1)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def test_tcp_replies_are_not_written_to_an_idle_pty(
    start_server: StartServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    pty_writes = _count_pty_writes(monkeypatch)
    server = start_server()
    with _connect(server) as connection:
        for _ in range(200):
            connection.sendall(b"#qd!")
            assert _read_frames(_recv(connection), 1) == b"$qd.0!"
    assert pty_writes == []
    assert server.pty_path is not None
    assert _nothing_readable(server.pty_path)


def test_each_link_gets_the_replies_to_its_own_queries_only(
    start_server: StartServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    pty_writes = _count_pty_writes(monkeypatch)
    server = start_server()
    with _open_pty(server) as port, _connect(server) as connection:
        for _ in range(20):
            connection.sendall(b"#qr!")
            assert _read_frames(_recv(connection), 1) == b"$qr.20!"
        # A byte stream is in order: a TCP reply written to the PTY would come before this one.
        port.write(b"#qd!")
        assert _read_frames(_reader(port), 1) == b"$qd.0!"
        connection.sendall(b"#q.l!")
        assert _read_frames(_recv(connection), 1) == b"$q.l.0!"
    assert b"".join(pty_writes) == b"$qd.0!"


def test_debug_lines_about_a_frame_go_to_its_link_lock_and_failsafe_lines_to_every_link(
    start_server: StartServer,
) -> None:
    config = SimConfig(controller=ControllerConfig(watchdog_s=0.5))
    server = start_server(config, speed=10.0)
    with _open_pty(server) as port, _connect(server) as connection:
        connection.sendall(b"#debug1!#start!#bogus!")
        tcp = b""
        pty = b""
        deadline = time.monotonic() + 10
        while b"failsafe" not in tcp or b"failsafe" not in pty or not pty.endswith(b"\r\n"):
            assert time.monotonic() < deadline, (tcp, pty)
            tcp += _recv(connection)()
            pty += port.read(256)
        assert b"debug output on" in tcp
        assert b"<bogus>" in tcp
        assert pty == (
            b"debug: motors unlocked\r\n"
            b"debug: failsafe: no valid frame for 0.5 s: motors stopped and locked\r\n"
        )


def test_baud_paces_the_byte_stream(start_server: StartServer) -> None:
    server = start_server(tcp=False, baud=1200)  # 8.3 ms a byte
    with _open_pty(server) as port:
        started = time.monotonic()
        port.write(b"#qsa!")
        reply = _read_frames(_reader(port), 6)
        elapsed_s = time.monotonic() - started
    # Not faster than the line (a loaded machine only makes it slower); that the rate is exactly
    # the baud rate's is checked, without a wall clock, in test_sim_pacing.
    line_time_s = (len(b"#qsa!") + len(reply)) * 10 / 1200
    assert elapsed_s >= 0.9 * line_time_s


def test_a_paced_tcp_client_that_stops_sending_still_gets_its_replies(
    start_server: StartServer,
) -> None:
    # `echo '#qsa!' | socat - TCP:…` (or `nc -N`): the client sends its queries, shuts its side
    # down and reads what comes. Before, at a paced rate the server closed the line as soon as
    # it read the end of the stream: the queries still on their way over the line were never
    # handled, and nothing came back.
    server = start_server(pty=False, baud=9600)  # 1 ms a byte
    with _connect(server) as connection:
        connection.sendall(b"#start!#qsa!")
        connection.shutdown(socket.SHUT_WR)
        reply = b""
        deadline = time.monotonic() + 5
        while (chunk := _recv_until_closed(connection, deadline)) is not None:
            reply += chunk
    assert reply.startswith(b"$qd.0!$qr.20!$q.l.0!$qro."), reply
    assert reply.count(b"!") == 6
    # The client is gone once it has been answered: its motion stops as when a link closes.
    assert wait_until(lambda: server.robot.controller.locked)


def test_a_paced_tcp_client_whose_connection_fails_is_let_go_at_once(
    start_server: StartServer,
) -> None:
    # A connection reset is no stream ended in order: what was still on its way over the paced
    # line is not handled (nobody is left to stop what it would start).
    server = start_server(pty=False, baud=300)  # `#start!` takes 0.23 s to arrive
    connection = _connect(server)
    assert wait_until(lambda: _served_tcp_client(server))  # accepted: the reset comes after
    connection.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    connection.sendall(b"#start!#h+!")
    connection.close()  # with a zero linger: a reset
    assert wait_until(lambda: not _served_tcp_client(server))
    assert server.robot.claw.history == []
    assert server.robot.controller.locked


def _served_tcp_client(server: SimServer) -> bool:
    return any(isinstance(line, TcpLine) for line in list(server._lines.lines))


def _recv_until_closed(connection: socket.socket, deadline: float) -> bytes | None:
    """The next bytes from ``connection``, b"" if none yet, None once the server closed it."""
    assert time.monotonic() < deadline, "the server neither answered nor closed the connection"
    try:
        return connection.recv(4096) or None
    except TimeoutError:
        return b""


def test_a_paced_line_makes_its_writer_wait_as_a_full_serial_port_does(
    start_server: StartServer,
) -> None:
    # Before, the server read whatever came at once and kept up to 64 KB (a minute at 9600 baud)
    # to hand the controller at the line's rate, and dropped the oldest beyond: a writer never
    # waited, and a #stop! it wrote reached the controller a minute late. A serial port's driver
    # takes some 4 KB, then its writer waits.
    server = start_server(tcp=False, baud=115200)  # 11.5 KB a second
    frames = b"#mgmp.180!" * 100  # (a set command: no reply to read)
    with _open_pty(server) as port:
        fd = port.fileno()
        os.set_blocking(fd, False)
        accepted_bytes = 0
        writing_s = 0.3
        deadline = time.monotonic() + writing_s
        while time.monotonic() < deadline:
            try:
                accepted_bytes += os.write(fd, frames)
            except BlockingIOError:
                select.select([], [fd], [], 0.01)
        # What the line carried meanwhile, the server's 4 KB and the pseudo-terminal's own
        # buffers (some 20 KB on Linux). Unbounded, it was megabytes.
        carried_bytes = writing_s * 115200 / 10
        assert accepted_bytes < carried_bytes + LINE_BUFFER_BYTES + 64 * 1024
    assert all(pacers.to_controller.dropped_bytes == 0 for pacers in server._pacers.values())


def test_a_speed_beyond_the_cpu_still_answers_at_once(start_server: StartServer) -> None:
    # A million simulated seconds a second is more ticks than any CPU runs: the server once
    # ran ever longer batches of them and answered nothing (a #stop! included) for minutes.
    server = start_server(pty=False, speed=1e6)
    with _connect(server) as connection:
        for _ in range(3):
            connection.sendall(b"#q.l!")
            assert _read_frames(_recv(connection), 1) == b"$q.l.0!"


def test_the_robot_dives_and_holds_one_metre_over_the_pty(start_server: StartServer) -> None:
    # Ten simulated seconds a second. The link-loss failsafe is off: it counts simulated
    # seconds, so one stall of this test's wall-clock polling would trip it.
    config = SimConfig(controller=ControllerConfig(watchdog_s=0.0))
    server = start_server(config, tcp=False, speed=10.0)
    with _open_pty(server) as port:
        port.write(b"#start!#mvd.100!")
        depths: list[int] = []
        deadline = time.monotonic() + 20
        while len(depths) < 12 or not all(95 <= depth <= 105 for depth in depths[-5:]):
            assert time.monotonic() < deadline, depths
            time.sleep(0.1)  # polls about once a simulated second
            port.write(b"#qd!")
            reply = _read_frames(_reader(port), 1)
            depths.append(int(reply[4:-1]))
        assert max(depths) <= 110


@pytest.mark.parametrize(
    ("text", "address"),
    [
        ("5760", ("127.0.0.1", 5760)),
        (":5760", ("127.0.0.1", 5760)),
        ("0.0.0.0:1", ("0.0.0.0", 1)),
        ("[::1]:80", ("::1", 80)),
    ],
)
def test_tcp_addresses(text: str, address: tuple[str, int]) -> None:
    assert parse_tcp_address(text) == address


@pytest.mark.parametrize("text", ["", "host:", "host:port", "1:99999"])
def test_bad_tcp_addresses(text: str) -> None:
    with pytest.raises(ValueError, match="HOST:PORT"):
        parse_tcp_address(text)


def test_a_client_that_closed_just_before_the_next_connected_gives_way_to_it() -> None:
    # A program run twice in a row: its last bytes and its hang-up, and the next one's
    # connection, wait in the same turn of the server. Before, the connection was handled first
    # (the listener's descriptor is the lower), and the new program read "busy".
    served: list[bytes] = []
    lines = Lines(lambda line, data: served.append(data), busy_message=BUSY_MESSAGE)
    try:
        address = lines.listen_tcp()
        with socket.create_connection(address, timeout=5) as first:
            deadline = time.monotonic() + 5
            while not lines.lines and time.monotonic() < deadline:  # (served in a turn or two)
                lines.wait(0.05)
            assert len(lines.lines) == 1
            first.sendall(b"#stop!")
        with socket.create_connection(address, timeout=5) as second:
            lines.wait(0.5)  # one turn: the first's hang-up and the second's connection
            assert served == [b"#stop!"]
            assert len(lines.lines) == 1
            served_line = lines.lines[0]
            assert isinstance(served_line, TcpLine)
            assert served_line.connection.getpeername() == second.getsockname()
    finally:
        lines.close()
