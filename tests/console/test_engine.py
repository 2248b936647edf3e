"""The console engine against a simulated controller: lines run in order, replies are shown,
the stop key jumps the queue, leaving sends #stop! unless locked as last sent."""

from __future__ import annotations

import asyncio
import contextlib
import socket

from rovlink.aio import AsyncClient
from rovlink.client.events import ClientEvent, LateReply
from rovlink.client.links import SocketLink
from rovlink.console.actions import Quit, SendCommand, SendRaw, SetChecksum, ShowStatus, parse_line
from rovlink.console.engine import ConsoleEngine
from rovlink.console.transcript import Line, plain_text
from rovlink.piloting import TrackedClient
from rovlink.protocol import Command
from tests.client.conftest import NO_REPLY_TIMEOUT_S, REPLY_TIMEOUT_S, client_options
from tests.piloting.rig import Rig, SilentController, until


class Screen:
    """Collects the engine's lines as text."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def __call__(self, line: Line) -> None:
        self.lines.append(plain_text(line))

    def text(self) -> str:
        return "\n".join(self.lines)


async def _engine(rig: Rig, **options: object) -> tuple[ConsoleEngine, Screen]:
    screen = Screen()
    engine = ConsoleEngine(screen)
    engine.attach(TrackedClient(await rig.connect(engine.on_event, **options)))
    return engine, screen


async def test_commands_run_in_order_and_replies_are_shown_with_their_frames() -> None:
    rig = Rig.simulated()
    engine, screen = await _engine(rig)
    runner = asyncio.create_task(engine.run())
    for command in (Command("debug1"), Command("start"), Command("mvd", (40,)), Command("qsa")):
        engine.submit(SendCommand(command))
    engine.submit(Quit())
    await asyncio.wait_for(runner, 5)
    assert rig.frames()[1:] == ["#debug1!", "#start!", "#mvd.40!", "#qsa!", "#stop!"]
    text = screen.text()
    assert "  → #mvd.40!" in text
    for words in ("qd → 0 cm", "$qd.0!", "q.l → no leak", "$q.l.0!", "qhe → "):
        assert words in text
    assert "⋯ debug: target depth 40 cm" in text  # the controller's debug line
    assert "leaving: sending #stop! (motors unlocked (as last sent))" in text
    await engine.rov.client.close()


async def test_stop_now_jumps_the_queue_and_drops_what_was_not_sent() -> None:
    silent = SilentController()
    # The #qd! must still be waiting when the stop key comes, however slow the machine: its
    # timeout is a long one, and the test waits it out at the end.
    options = client_options(timeout_s=REPLY_TIMEOUT_S, retries=0)
    client = await AsyncClient(silent.link(), options).open()
    screen = Screen()
    engine = ConsoleEngine(screen)
    engine.attach(TrackedClient(client))
    runner = asyncio.create_task(engine.run())
    engine.submit(SendCommand(Command("qd")))  # waits for a reply that never comes
    engine.submit(SendCommand(Command("start")))
    engine.submit(SendCommand(Command("th", (0, 100))))
    await until(lambda: b"#qd!" in silent.received)
    assert engine.queued == 2
    await engine.stop_now()
    assert engine.queued == 0
    await until(lambda: b"#stop!" in silent.received)
    engine.submit(Quit())
    await asyncio.wait_for(runner, REPLY_TIMEOUT_S + 5)  # the #qd! times out first
    # Nothing of the dropped lines; after the timeout, the session's own fence (P20).
    assert bytes(silent.received).startswith(b"#crcoff!#qd!#stop!")
    assert b"#start!" not in silent.received
    assert b"#th." not in silent.received
    assert "■ STOP (Ctrl-X); 2 queued line(s) dropped" in screen.text()
    assert "#qd! got no valid reply" in screen.text()
    await client.close()
    silent.close()


async def test_checksum_mode_and_raw_frames() -> None:
    rig = Rig.simulated()
    engine, screen = await _engine(rig)
    await engine.execute(SetChecksum(True))
    await engine.execute(SendCommand(Command("qd")))
    await engine.execute(SendRaw("#qd!"))  # no checksum: the controller drops it
    await engine.execute(ShowStatus())
    assert rig.frames()[1:3] == ["#crcon!", "#qd8C!"]
    text = screen.text()
    assert "checksum mode on" in text
    assert "$qd.0" in text
    assert "qd → 0 cm" in text
    assert "  → #qd!   not a command the controller takes as it stands" in text
    assert text.count("qd → ") == 1
    assert "checksum:   on (crc8)" in text
    await engine.rov.client.close()


async def test_leaving_while_locked_sends_nothing_more() -> None:
    rig = Rig.simulated()
    engine, _ = await _engine(rig)
    runner = asyncio.create_task(engine.run())
    engine.submit(SendCommand(Command("stop")))
    engine.submit(Quit())
    await asyncio.wait_for(runner, 5)
    assert rig.frames() == ["#crcoff!", "#stop!"]
    await engine.rov.client.close()


async def test_a_raw_line_of_two_frames_is_refused_and_leaving_still_stops() -> None:
    # Before, `raw #start!#th.0.50!` went out untracked: the status said locked, and `quit`
    # after an earlier `stop` sent no #stop! to the robot driving at 50 %.
    rig = Rig.simulated()
    engine, screen = await _engine(rig)
    runner = asyncio.create_task(engine.run())
    engine.submit(SendCommand(Command("stop")))
    engine.submit(SendRaw("#start!#th.0.50!"))
    engine.submit(SendRaw("#start!"))
    engine.submit(Quit())
    await asyncio.wait_for(runner, 5)
    assert "holds 2 commands (#start!, #th.0.50!); send each on its own" in screen.text()
    assert rig.frames()[1:] == ["#stop!", "#start!", "#stop!"]
    await engine.rov.client.close()


async def test_a_start_split_over_two_raw_lines_is_stopped_on_leaving() -> None:
    rig = Rig.simulated()
    engine, _ = await _engine(rig)
    runner = asyncio.create_task(engine.run())
    engine.submit(SendCommand(Command("stop")))
    engine.submit(SendRaw("#sta"))
    engine.submit(SendRaw("rt!"))
    engine.submit(Quit())
    await asyncio.wait_for(runner, 5)
    assert rig.frames()[-1] == "#stop!"
    assert rig.frames().count("#stop!") == 2  # (the one typed, and the one on leaving)
    await engine.rov.client.close()


async def test_status_says_the_link_is_lost() -> None:
    rig = Rig.simulated()
    engine, screen = await _engine(rig)
    rig.port.close()
    await until(lambda: engine.rov.client.closed)  # (said by the next read of the port)
    await engine.execute(ShowStatus())
    (link,) = [line for line in screen.lines if line.startswith("link:")]
    assert "link lost" in link
    assert "waiting" not in link
    await engine.rov.client.close()


async def test_a_reply_after_its_query_timed_out_is_shown_as_late() -> None:
    # Before, a reply that came after its query's timeout was dropped without a word: the
    # console said "got no valid reply" of a controller that did answer, only slowly.
    host_end, controller_end = socket.socketpair()
    options = client_options(timeout_s=NO_REPLY_TIMEOUT_S, retries=0)
    client = await AsyncClient(SocketLink(host_end, "slow controller"), options).open()
    screen = Screen()
    engine = ConsoleEngine(screen)
    engine.attach(TrackedClient(client))
    await engine.execute(SendCommand(Command("qd")))
    assert "#qd! got no valid reply" in screen.text()
    controller_end.sendall(b"$qd.5!")
    await until(lambda: "late: its query had timed out" in screen.text())
    assert "  qd → 5 cm                 $qd.5!  late: its query had timed out" in screen.lines
    await client.close()
    controller_end.close()


async def test_a_late_reply_to_a_keepalive_is_not_shown_as_a_reply() -> None:
    # Before, the reply to the driver's own keep-alive that came after the keep-alive had timed
    # out was shown as "qd → 5 cm … late": the pilot read it as the answer to a line they typed.
    host_end, controller_end = socket.socketpair()
    controller_end.setblocking(False)
    options = client_options(timeout_s=NO_REPLY_TIMEOUT_S, retries=0, keepalive_s=0.05)
    client = await AsyncClient(SocketLink(host_end, "slow controller"), options).open()
    screen = Screen()
    engine = ConsoleEngine(screen)
    engine.attach(TrackedClient(client))
    events: list[ClientEvent] = []
    client.subscribe(events.append)  # (called after the engine's subscription)
    received = bytearray()

    def heard(frame: bytes) -> bool:
        with contextlib.suppress(BlockingIOError):
            received.extend(controller_end.recv(4096))
        return frame in received

    await until(lambda: heard(b"#qhe!"))  # the keep-alive's #qd! timed out: fenced
    controller_end.sendall(b"$qd.5!$qhe.10!")  # the keep-alive's reply, late, then the fence's
    await until(lambda: any(isinstance(event, LateReply) for event in events))
    assert "qd →" not in screen.text()
    await client.close()
    controller_end.close()


async def test_help_exit_shows_quit_and_the_console_goes_on() -> None:
    # Before, `help exit` raised in the engine (exit is quit's other name, not in the table):
    # the lines typed after it were never run, and the console ended as a usage error.
    rig = Rig.simulated()
    engine, screen = await _engine(rig)
    action = parse_line("help exit")
    assert action is not None
    await engine.execute(action)
    assert "quit" in screen.lines
    assert (
        "  leave (sends #stop! first unless locked as last sent); also exit, Ctrl-D" in screen.lines
    )
    await engine.execute(SendCommand(Command("qd")))
    assert "qd → 0 cm" in screen.text()
    await engine.rov.client.close()
