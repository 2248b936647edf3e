"""The monitor end to end through textual's pilot: what it shows and which frames reached the
(simulated, or silent) controller."""

from __future__ import annotations

import asyncio
import logging
import re
import threading
from collections.abc import Awaitable, Callable
from typing import Any

import pytest
from textual import events
from textual.pilot import Pilot

import rovlink.aio.client
from rovlink.aio import AsyncClient
from rovlink.cli import build_parser, main
from rovlink.cli import monitor as cli_monitor
from rovlink.cli.monitor import build_app
from rovlink.client.links import Link, PortLink
from rovlink.client.options import StrayCallback
from rovlink.monitor.app import MonitorApp
from rovlink.piloting.tracked import STOP_KEPT_NOTICE, STOP_UNSENT_NOTICE
from rovlink.protocol import BadFrame, Reason
from rovlink.protocol import Text as DebugText
from tests.client.conftest import (
    CONDITION_TIMEOUT_S,
    NO_REPLY_TIMEOUT_S,
    client_options,
)
from tests.client.fake_controller import FakeControllerServer
from tests.monitor.screen import screen_text, shown
from tests.piloting.rig import RecordingLink, Rig, SilenceableLink, SilentController, until

SIZE = (100, 34)


def _commands(rig: Rig) -> list[str]:
    """The frames sent, polls left out."""
    return [frame for frame in rig.frames() if frame != "#qsa!"]


def _depth_shown(app: MonitorApp) -> int | None:
    value = shown(app, "#depth-digits")
    return int(value) if value.isdigit() else None


async def test_drive_to_a_depth_and_back_then_stop() -> None:
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("s")
        assert "unlocked (as last sent)" in shown(app, "#commanded")
        await pilot.press("pagedown", "pagedown", "pagedown")
        assert _commands(rig)[1:] == ["#start!", "#mvdirect.0!", "#mvd.10!", "#mvd.20!", "#mvd.30!"]
        assert "target 30 cm, as last sent" in shown(app, "#depth-readout")
        rig.port.advance(20.0)  # simulated seconds: the depth PID takes it down
        await until(lambda: abs((_depth_shown(app) or 0) - 30) <= 4)
        await pilot.press("pageup", "pageup", "pageup")
        rig.port.advance(30.0)
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("right", "up", "up", "left", "down", "o", "c")
        await pilot.press("space")
        assert "locked (as last sent)" in shown(app, "#commanded")
        chart = shown(app, "#chart")
        assert "•" in chart
        assert "30 cm" in chart or "50 cm" in chart
        await pilot.press("q")
    assert _commands(rig)[6:] == [
        "#mvd.20!",
        "#mvd.10!",
        "#mvd.0!",
        "#th.15.0!",
        "#th.15.10!",
        "#th.15.20!",
        "#th.0.20!",
        "#th.0.10!",
        "#h+!",
        "#h-!",
        "#stop!",
    ]  # q while locked (as last sent): nothing more
    assert rig.port.controller.locked


async def test_keys_pressed_while_locked_show_as_last_sent() -> None:
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("space", "right")
        await until(lambda: "#th.15.0!" in rig.frames())
        assert "#th.15.0!  (dropped: locked)" in shown(app, "#commanded")
        await pilot.press("q")


async def test_controller_text_shows_its_control_characters_escaped() -> None:
    # Regression: an escape sequence in a controller line reached the terminal as is.
    rig = Rig.simulated()
    strays: list[StrayCallback] = []

    async def connect(on_stray: StrayCallback) -> AsyncClient:
        strays.append(on_stray)
        return await rig.connect(on_stray)

    app = MonitorApp(connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        strays[0](DebugText("\x1b[31mRED\x07"))
        await until(lambda: "\\x1b[31mRED\\x07" in shown(app, "#commanded"))
        assert "\x1b" not in shown(app, "#commanded")
        await pilot.press("q")


async def test_a_dropped_reply_is_shown_as_the_controller_wrote_it() -> None:
    # Before, as Python wrote the bytes: "dropped reply b'$qd.12X!': …".
    rig = Rig.simulated()
    strays: list[StrayCallback] = []

    async def connect(on_stray: StrayCallback) -> AsyncClient:
        strays.append(on_stray)
        return await rig.connect(on_stray)

    app = MonitorApp(connect, description="bench", rate_hz=20)
    async with app.run_test(size=(140, 34)) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        strays[0](BadFrame(Reason.MALFORMED, b"$qd.1\x1b2!", "not a number"))
        await until(lambda: "dropped reply $qd.1\\x1b2!: not a number" in shown(app, "#commanded"))
        await pilot.press("q")


async def test_leaving_without_q_stops_the_robot_it_moved() -> None:
    # SIGINT or SIGTERM ends the app without the q key: #stop! is still the last frame.
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("s", "up")
        await until(lambda: "#th.0.10!" in rig.frames())
        app.exit()
    assert _commands(rig)[-1] == "#stop!"
    assert rig.port.controller.locked


class FakeClock:
    """Monotonic seconds that move only when a test moves them."""

    def __init__(self, now_s: float = 1000.0) -> None:
        self.now_s = now_s

    def __call__(self) -> float:
        return self.now_s


READING_BOXES = ("#depth-box", "#attitude", "#leak")


async def test_every_reading_shown_is_marked_stale_when_the_link_is_cut() -> None:
    # Regression: only the depth box said "stale"; the depth figure, roll, pitch, heading, the
    # compass and a green "no leak (q.l = 0)" went on looking live.
    rig = Rig.simulated()
    clock = FakeClock()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20, clock=clock)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: "no leak (q.l = 0)" in shown(app, "#leak"))
        assert not app.query(".-stale")
        rig.port.close()
        await until(lambda: "lost: " in shown(app, "#link"))  # no reading will come now
        clock.now_s += 6.5
        await until(lambda: app.query_one("#attitude").has_class("-stale"))
        for box in READING_BOXES:
            assert app.query_one(box).has_class("-stale"), box
            assert app.query_one(box).border_subtitle == "stale: 6.5 s old", box
        await until(lambda: screen_text(app).count("stale: 6.5 s old") == 3)
        assert shown(app, "#leak") == "leak unknown: the last reading said no leak (q.l = 0)"
        await pilot.press("q")


async def test_the_controllers_last_message_shows_its_age_once_stale() -> None:
    # Regression: a controller message of minutes ago was shown as one of now.
    rig = Rig.simulated()
    strays: list[StrayCallback] = []

    async def connect(on_stray: StrayCallback) -> AsyncClient:
        strays.append(on_stray)
        return await rig.connect(on_stray)

    clock = FakeClock()
    app = MonitorApp(connect, description="bench", rate_hz=20, clock=clock)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        strays[0](DebugText("debug: hold"))
        await until(lambda: "debug: hold" in shown(app, "#commanded"))
        assert "ago" not in shown(app, "#commanded")
        clock.now_s += 6.5
        await until(lambda: "debug: hold  (6.5 s ago)" in shown(app, "#commanded"))
        await pilot.press("q")


async def test_leak_alarm_and_reset() -> None:
    rig = Rig.simulated(leak_at_s=1.0)
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: "no leak (q.l = 0)" in shown(app, "#leak"))
        assert not app.query_one("#leak").has_class("alarm")
        rig.port.advance(2.0)
        await until(lambda: app.query_one("#leak").has_class("alarm"))
        assert "██ LEAK ██" in shown(app, "#leak")
        assert app.screen.has_class("leak")
        assert "LEAK" in screen_text(app)
        await pilot.press("r")
        await until(lambda: not app.query_one("#leak").has_class("alarm"))
        assert "no leak (q.l = 0)" in shown(app, "#leak")
        await pilot.press("q")
    assert "#slreset!" in _commands(rig)
    assert _commands(rig)[-1] == "#stop!"  # lock unknown on leaving: made safe


def _silent_app(silent: SilentController, reply_timeout_s: float) -> MonitorApp:
    def connect(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
        options = client_options(timeout_s=reply_timeout_s, retries=0, on_stray=on_stray)
        return AsyncClient(silent.link(), options).open()

    return MonitorApp(connect, description="silent", rate_hz=10)


async def test_keys_still_work_while_a_poll_waits_for_its_reply() -> None:
    silent = SilentController()
    # A poll that waits far longer than any machine takes to handle a key: the stop cannot
    # have waited for it.
    app = _silent_app(silent, reply_timeout_s=30 * CONDITION_TIMEOUT_S)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: b"#qsa!" in silent.received)  # a poll is waiting for its reply
        await pilot.press("space")
        await until(lambda: silent.received.endswith(b"#stop!"))
        assert app.rov is not None
        assert app.rov.health.failures == 0  # sent while the poll still waited
        await pilot.press("q")
    silent.close()


async def test_a_silent_link_degrades_link_health_while_keys_still_work() -> None:
    silent = SilentController()
    app = _silent_app(silent, reply_timeout_s=NO_REPLY_TIMEOUT_S)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: "no reply" in shown(app, "#link"))
        link = shown(app, "#link")
        assert "no reading yet" in link
        assert re.search(r"timeouts [1-9]", link)
        await pilot.press("s")
        # (Fences and mode frames of the resynchronising session may follow, P20, P21.)
        await until(lambda: b"#start!" in silent.received)
        assert shown(app, "#depth-digits") == "—"
        await pilot.press("q")
        await until(lambda: silent.received.rfind(b"#stop!") > silent.received.rfind(b"#start!"))
    silent.close()


async def test_a_depth_key_with_no_depth_reading_sends_no_target() -> None:
    # Before, PgDn with no reading yet (a silent sensor link) sent #mvd.10!: the step was taken
    # from 0 cm, and a robot at 3 m rose to 10 cm.
    silent = SilentController()
    app = _silent_app(silent, reply_timeout_s=NO_REPLY_TIMEOUT_S)
    notified = _record_notifications(app)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: "no reply" in shown(app, "#link"))
        await pilot.press("s", "pagedown", "pageup")
        await until(lambda: b"#start!" in silent.received)
        await until(lambda: len([text for text in notified if "no depth reading" in text]) == 2)
        assert b"#mvd." not in silent.received
        assert b"#mvdirect." not in silent.received
        await pilot.press("q")
    silent.close()


async def test_a_depth_key_with_only_a_stale_depth_reading_sends_no_target() -> None:
    # Before, PgDn with the link gone quiet took its step from the last depth, however old:
    # a robot read at 50 cm a minute ago, sinking since, was sent back up to 60 cm.
    port = Rig.simulated().port
    link = SilenceableLink(PortLink(port, "simulated controller"))
    rig = Rig(port, link)

    def connect(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
        return rig.connect(on_stray, timeout_s=NO_REPLY_TIMEOUT_S, retries=0)

    clock = FakeClock()
    app = MonitorApp(connect, description="bench", rate_hz=20, clock=clock)
    notified = _record_notifications(app)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        link.silent.set()  # the replies stop coming
        clock.now_s += 6.5
        await until(lambda: app.query_one("#depth-box").has_class("-stale"))
        await pilot.press("s", "pagedown")
        await until(lambda: "#start!" in rig.frames())
        await until(lambda: any("the depth reading is stale: 6.5 s old" in t for t in notified))
        assert not [frame for frame in rig.frames() if frame.startswith(("#mvd", "#mvdirect"))]
        await pilot.press("q")


async def test_a_failed_connection_is_shown_and_q_still_quits() -> None:
    async def connect(on_stray: StrayCallback) -> AsyncClient:
        raise ConnectionRefusedError("nothing listening")

    app = MonitorApp(connect, description="nowhere")
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: "could not connect: nothing listening" in shown(app, "#link"))
        await pilot.press("space")  # nothing to send to: says so, does not crash
        await pilot.press("q")
    assert app.return_code == 0


async def test_footer_shows_the_keys() -> None:
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench")
    async with app.run_test(size=SIZE) as pilot:

        def footer() -> str:
            return [line for line in screen_text(app).splitlines() if line.strip()][-1]

        await until(lambda: "q quit" in footer())
        for words in (
            "space STOP",
            "s start",
            "←→ turn",
            "↑↓ power",
            "PgUp/PgDn depth",
            "o/c claw",
            "r reset leak",
            "q quit",
        ):
            assert words in footer()
        await pilot.press("q")


async def test_with_caps_lock_on_the_letter_keys_do_what_they_say() -> None:
    # Before, "Q" (caps lock on) did nothing, nor did "S": the dashboard would not quit.
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("S", "O", "C", "R", "Q")
        await until(lambda: not app.is_running)
    assert _commands(rig)[1:] == ["#start!", "#h+!", "#h-!", "#slreset!", "#stop!"]


async def test_a_click_on_the_footer_drives_nothing() -> None:
    # Regression: a press of the mouse button on "s start" (the click that focuses the
    # terminal's window) unlocked the motors, and one on "↑↓ power" sent thrust.
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0 and "q quit" in screen_text(app))
        footer_row = screen_text(app).splitlines()[SIZE[1] - 1]
        for words in ("s start", "↑↓ power"):
            column = footer_row.index(words) + 1
            for event in (events.MouseDown, events.MouseUp):  # as the terminal reports a click
                app.post_message(event(None, column, SIZE[1] - 1, 0, 0, 1, False, False, False))
        await pilot.pause()
        await pilot.press("space")  # (a frame behind any the clicks sent)
        await until(lambda: "#stop!" in rig.frames())
        assert _commands(rig)[1:] == ["#stop!"]
        await pilot.press("q")


async def test_the_classic_80_by_24_terminal_shows_every_essential_row_and_the_quit_key() -> None:
    # Regression: at 80×24 the "commanded" box was 14 columns wide ("motors unlocked (as last
    # sent)" over three lines, "horizontal" and "last sent" cut off), the screen scrolled, and
    # the footer ended before "q quit".
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=(80, 24)) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("s")
        await until(lambda: "motors     unlocked (as last sent)" in screen_text(app))
        await pilot.press("space", "right")
        await until(lambda: "#th.15.0!" in rig.frames())
        await until(lambda: "last sent  #th.15.0!  (dropped: locked)" in screen_text(app))
        lines = screen_text(app).splitlines()
        assert len(lines) == 24
        assert lines[-1].rstrip().endswith("q quit")
        screen = "\n".join(lines)
        for row in (
            "motors     locked (as last sent)",
            "vertical   unknown: none sent",
            "horizontal 0° at 0 %",
            "raw pressure",
            "roll ",
            "pitch ",
            "heading ",
            "▲",
            "no leak (q.l = 0)",
            "link       simulated controller · polling 20 Hz",
            "reply time ",
            "silence    last reading",
            "errors     timeouts 0 · retries 0 · checksum errors 0 · failed polls 0",
        ):
            assert row in screen, row
        assert app.screen.virtual_size.height <= 24  # nothing below the fold to scroll to
        await pilot.resize_terminal(120, 40)  # wider: three boxes in a row, and the chart
        await until(lambda: "depth over time" in screen_text(app))
        assert "depth, cm" in screen_text(app).splitlines()[1]
        assert "commanded, as last sent" in screen_text(app).splitlines()[1]
        await pilot.press("q")


def _record_links(monkeypatch: pytest.MonkeyPatch) -> list[RecordingLink]:
    links: list[RecordingLink] = []
    open_link = rovlink.aio.client.open_link  # type: ignore[attr-defined]

    def recording_open_link(endpoint: object) -> Link:
        link = RecordingLink(open_link(endpoint))  # type: ignore[arg-type]
        links.append(link)
        return link

    monkeypatch.setattr(rovlink.aio.client, "open_link", recording_open_link)
    return links


async def test_monitor_on_sim_url_shows_an_injected_leak(monkeypatch: pytest.MonkeyPatch) -> None:
    """``rovlink monitor 'sim://?leak_at=…'``: the real URL, the simulator in real time."""
    links = _record_links(monkeypatch)
    app = build_app(
        build_parser("monitor").parse_args(["monitor", "sim://?leak_at=0.3&seed=1", "--rate", "20"])
    )
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: app.query_one("#leak").has_class("alarm"))
        assert "sim://?leak_at=0.3&seed=1" in screen_text(app)
        await pilot.press("space")
        await pilot.press("q")
    (link,) = links
    assert "#stop!" in link.frames()


def test_cli_monitor_connects_then_runs_the_dashboard(monkeypatch: pytest.MonkeyPatch) -> None:
    # The command opens the port before the dashboard starts, and hands it the client.
    run_async = MonitorApp.run_async

    async def headless(self: MonitorApp, **options: object) -> None:
        async def drive(pilot: Pilot[object]) -> None:
            await until(lambda: self.readings.latest is not None)
            await pilot.press("q")

        await run_async(self, headless=True, size=SIZE, auto_pilot=drive)

    monkeypatch.setattr(MonitorApp, "run_async", headless)
    monkeypatch.setattr(cli_monitor, "missing_terminal", lambda: None)  # (drawn headless)
    assert main(["monitor", "sim://?seed=1", "--rate", "20"]) == 0


def test_cli_monitor_refuses_bad_options(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["monitor", "sim://?nosuch=1"]) == 2
    assert "unknown sim option 'nosuch'" in capsys.readouterr().err
    assert main(["monitor", "--algorithm", "md5"]) == 2
    assert "unknown checksum algorithm 'md5'" in capsys.readouterr().err
    assert main(["monitor", "--rate", "0"]) == 2
    assert "argument --rate: 0 Hz is less than the minimum, 0.1 Hz" in capsys.readouterr().err


def test_rate_must_be_positive() -> None:
    async def never(on_stray: StrayCallback) -> AsyncClient:
        raise AssertionError

    connect: Callable[[StrayCallback], Awaitable[AsyncClient]] = never
    with pytest.raises(ValueError, match="rate_hz"):
        MonitorApp(connect, rate_hz=0)


def _record_notifications(app: MonitorApp) -> list[str]:
    """The messages ``app`` notifies from now on (and shows, as ever)."""
    notified: list[str] = []
    notify = app.notify

    def recording_notify(message: str, **options: Any) -> None:
        notified.append(message)
        notify(message, **options)

    app.notify = recording_notify  # type: ignore[method-assign]
    return notified


async def test_a_lost_link_shows_as_lost_and_its_warning_as_a_notification() -> None:
    # The port closes between two polls (an adapter unplugged, a simulator ended): the link
    # panel says so, not "ok"; the library's warnings are notifications, not text written
    # over the dashboard's screen.
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=2)
    notified = _record_notifications(app)
    library_logger = logging.getLogger("rovlink")
    handlers_before = list(library_logger.handlers)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        rig.port.close()
        await until(lambda: "lost: " in shown(app, "#link"))  # (said by the next poll)
        link = shown(app, "#link")
        assert "link closed: keys send nothing" in link
        assert " ok " not in link
        logging.getLogger("rovlink.client").warning("a warning while the dashboard runs")
        assert "a warning while the dashboard runs" in notified
        await pilot.press("q")
    assert library_logger.handlers == handlers_before  # to stderr again, once it is gone
    assert library_logger.propagate


async def test_a_warning_from_another_thread_never_waits_for_the_dashboard() -> None:
    # The simulated controller of sim:// logs on its own thread while the dashboard's loop may
    # be waiting for that very thread: the warning is queued for the loop, never waited for.
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=2)
    notified = _record_notifications(app)
    async with app.run_test(size=SIZE) as pilot:
        logging_thread = threading.Thread(
            target=lambda: logging.getLogger("rovlink.sim").warning("leak detected")
        )
        logging_thread.start()
        logging_thread.join(timeout=2.0)  # (the loop is blocked here, as it can be)
        assert not logging_thread.is_alive()
        await until(lambda: "leak detected" in notified)
        await pilot.press("q")


async def test_a_terminal_too_small_for_the_boxes_shows_the_essentials_and_the_keys() -> None:
    # Before, at 20×5 the screen scrolled to a cut attitude box: no depth, no state as last
    # sent, no link, and the footer ended at "s start" (no "q quit"); at 80×15 the link box
    # was below the fold.
    rig = Rig.simulated()
    app = MonitorApp(rig.connect, description="bench", rate_hz=20)
    async with app.run_test(size=(20, 5)) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("s", "up")
        await until(lambda: "#th.0.10!" in rig.frames())
        await until(lambda: "motors unlocked · 0…" in screen_text(app))
        lines = [line.rstrip() for line in screen_text(app).splitlines()]
        assert lines == [
            "space STOP · q quit",
            "depth 0 cm",
            "motors unlocked · 0…",
            "link ok",
            "terminal 20×5: too …",
        ]
        assert app.screen.virtual_size.height <= 5  # nothing below the fold
        await pilot.resize_terminal(80, 15)
        await until(lambda: "terminal 80×15: too small" in screen_text(app))
        assert "0° at 10 % (as last sent)" in screen_text(app)
        await pilot.resize_terminal(80, 24)  # big enough: the boxes are back
        await until(lambda: screen_text(app).splitlines()[-1].rstrip().endswith("q quit"))
        assert "commanded, as last sent" in screen_text(app)
        await pilot.resize_terminal(20, 5)
        await until(lambda: screen_text(app).startswith("space STOP · q quit"))
        await pilot.press("q")
    assert _commands(rig)[-3:] == ["#start!", "#th.0.10!", "#stop!"]


async def test_q_ends_the_monitor_at_once_while_a_poll_waits_for_its_reply() -> None:
    # Before, q sent #stop!, then waited for the poll on the wire for the whole reply timeout
    # (--timeout, up to an hour) before the monitor ended.
    silent = SilentController()

    def connect(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
        options = client_options(timeout_s=30.0, retries=0, on_stray=on_stray)
        return AsyncClient(silent.link(), options).open()

    app = MonitorApp(connect, description="silent", rate_hz=10)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: b"#qsa!" in silent.received)  # a poll is waiting for its reply
        await pilot.press("s")
        await until(lambda: b"#start!" in silent.received)
        await asyncio.wait_for(pilot.press("q"), CONDITION_TIMEOUT_S)  # (it waits for q's action)
        await until(lambda: app.return_code is not None)
    await until(lambda: silent.received.endswith(b"#stop!"))  # (as the far end reads it)
    silent.close()


async def test_a_suspected_controller_reset_shows_the_lock_and_mode_unknown() -> None:
    # Before, the box went on saying "unlocked (as last sent)" at 10 % after the reset, while
    # the controller, locked, dropped every key's frame.
    rig = Rig.simulated()

    def connect(on_stray: StrayCallback) -> Awaitable[AsyncClient]:
        return rig.connect(on_stray, checksum=True, timeout_s=0.1, retries=2)

    app = MonitorApp(connect, description="bench", rate_hz=20)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 0)
        await pilot.press("s", "pagedown", "up")
        await until(lambda: "horizontal 0° at 10 %" in shown(app, "#commanded"))
        rig.port.controller.reset()  # checksum off: the polls go unanswered until re-sent
        await until(lambda: "motors     unknown: reset suspected" in shown(app, "#commanded"))
        commanded = shown(app, "#commanded")
        assert "vertical   unknown: reset suspected" in commanded
        assert "horizontal 0° at 0 %" in commanded
        await pilot.press("q")
    assert _commands(rig)[-1] == "#stop!"  # (the lock unknown: leaving stops)


@pytest.mark.integration
async def test_a_lost_link_is_reopened_and_the_polls_go_on() -> None:
    # Before, the first poll after the loss ended the polling for good ("link closed: keys
    # send nothing") though the adapter was plugged back at once.
    port = FakeControllerServer()
    args = build_parser("monitor").parse_args(
        ["monitor", port.url, "--boot-timeout", "0", "--rate", "20"]
    )
    app = build_app(args)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 123)
        await pilot.press("s", "up")
        await until(lambda: "#th.0.10!" in port.fakes[0].frames())
        port.fakes[0].close()
        await until(lambda: len(port.fakes) == 2)
        await until(lambda: "#qsa!" in port.fakes[1].frames())  # polling the reopened link
        await until(lambda: "motors     unknown: link reopened" in shown(app, "#commanded"))
        assert "horizontal 0° at 0 %" in shown(app, "#commanded")
        # Before, "last sent  #th.0.10!": sent on the old link, and undone on the new one.
        assert "last sent  — since the link was reopened" in shown(app, "#commanded")
        await until(lambda: "lost" not in shown(app, "#link"))
        await pilot.press("q")
    await until(lambda: "#stop!" in port.fakes[1].frames())  # (as the fake reads it)
    port.close()


@pytest.mark.integration
async def test_at_80_by_24_a_link_being_reopened_says_so_and_keeps_its_error_counts_on_screen() -> (
    None
):
    # Before, the link row read "lost: connection lost: tcp …: not reopened within 0.5 s
    # (reconnecting) · polling 20 Hz ·": two lines at 80 columns, which pushed the health and
    # the row of timeouts and failed polls out of the box.
    port = FakeControllerServer()
    args = build_parser("monitor").parse_args(
        ["monitor", port.url, "--boot-timeout", "0", "--rate", "20"]
    )
    app = build_app(args)
    async with app.run_test(size=(80, 24)) as pilot:
        await until(lambda: _depth_shown(app) == 123)
        port.refuse = True  # (unplugged, and not yet plugged back)
        port.fakes[0].close()
        await until(lambda: "lost, reopening it" in shown(app, "#link"))
        # All of it on one screen, polls failed meanwhile (stale readings); waited for as one
        # condition, as a busy machine may draw the rows a frame apart.
        wanted = (
            f"link       tcp 127.0.0.1:{port.url.rsplit(':', 1)[1]} · polling 20 Hz",
            "lost, reopening it",
            "errors     timeouts 0 · retries 0 · checksum errors 0 · failed polls",
            "stale",
        )
        await until(lambda: all(part in screen_text(app) for part in wanted), timeout_s=10.0)
        await pilot.press("q")
    port.close()


@pytest.mark.integration
async def test_a_stop_while_the_link_is_down_says_it_is_kept_and_leaving_says_it_never_went() -> (
    None
):
    # Before, space with the link down changed nothing on screen (the box still read "unlocked",
    # last sent the motion) and q left without a word: the #stop! had gone nowhere.
    port = FakeControllerServer()
    args = build_parser("monitor").parse_args(
        ["monitor", port.url, "--boot-timeout", "0", "--rate", "20"]
    )
    app = build_app(args)
    notified = _record_notifications(app)
    async with app.run_test(size=SIZE) as pilot:
        await until(lambda: _depth_shown(app) == 123)
        await pilot.press("s", "up")
        await until(lambda: "#th.0.10!" in port.fakes[0].frames())
        port.refuse = True  # (unplugged, and not yet plugged back)
        port.fakes[0].close()
        await until(lambda: "lost, reopening it" in shown(app, "#link"))
        await pilot.press("space")
        await until(lambda: STOP_KEPT_NOTICE in notified)
        assert app.stop_unsent is None
        await pilot.press("q")
    assert app.stop_unsent == STOP_UNSENT_NOTICE
    port.close()


def test_leaving_with_the_link_down_is_said_on_stderr(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The dashboard is gone by then: the line goes where a terminal keeps it.
    run_async = MonitorApp.run_async

    async def headless(self: MonitorApp, **options: object) -> None:
        async def drive(pilot: Pilot[object]) -> None:
            await until(lambda: self.readings.latest is not None)
            self.stop_unsent = STOP_UNSENT_NOTICE  # (as leaving with the link down sets it)
            await pilot.press("q")

        await run_async(self, headless=True, size=SIZE, auto_pilot=drive)

    monkeypatch.setattr(MonitorApp, "run_async", headless)
    monkeypatch.setattr(cli_monitor, "missing_terminal", lambda: None)  # (drawn headless)
    # (Before, the status was 0, as after a stop that went: a script could not tell.)
    assert main(["monitor", "sim://?seed=1", "--rate", "20"]) == 1
    assert capsys.readouterr().err == f"rovlink monitor: {STOP_UNSENT_NOTICE}\n"
