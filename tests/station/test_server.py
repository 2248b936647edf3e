"""The station's server over real sockets: ``rovlink web`` in a subprocess, a simulated robot on
TCP recording what reaches its controller, and WebSocket clients that speak as pages do."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import signal
import socket
import time
import urllib.error
import urllib.request
from collections.abc import AsyncIterator
from typing import Any

import pytest
from websockets.asyncio.client import connect
from websockets.exceptions import ConnectionClosed, InvalidStatus

from rovlink.protocol import lookup
from rovlink.station.hub import TELEMETRY_LOST_S, TELEMETRY_LOST_STATUS
from tests.client.fake_controller import FakeControllerServer
from tests.station.page_socket import PageSocket
from tests.station.rig import ControllerLine, StationProcess, running_station
from tests.station.test_hub import until

pytestmark = pytest.mark.integration

#: The pilot is promised zero thrust within this long of a stale pad, a dropped socket...
CUT_WITHIN_S = 0.5


async def pilot(station: StationProcess) -> PageSocket:
    page = await PageSocket.open(station.ws_url)
    await page.send({"type": "take_control"})
    await page.next("control", lambda m: m["pilot_id"] == page.id)
    return page


def held(direction_deg: int = 90, power_percent: int = 60, pad_ms: float = 0.0) -> dict[str, Any]:
    return {
        "type": "input",
        "deadman": True,
        "direction_deg": direction_deg,
        "power_percent": power_percent,
        "vertical_percent": 0,
        "pad_timestamp_ms": pad_ms,
    }


RELEASED = {
    "type": "input",
    "deadman": False,
    "direction_deg": 0,
    "power_percent": 0,
    "vertical_percent": 0,
    "pad_timestamp_ms": 0.0,
}


async def fly(page: PageSocket, line: ControllerLine, direction_deg: int = 90) -> None:
    """Unlock, arm (dead-man released) and hold the stick until ``#th.D.60!`` reaches the robot."""
    mark = line.mark()
    await page.send({"type": "command", "name": "start"})
    await asyncio.to_thread(line.wait_for, "#start!", after=mark)
    await page.send(RELEASED)
    await page.send(held(direction_deg, pad_ms=1.0))
    await asyncio.to_thread(line.wait_for, f"#th.{direction_deg}.60!", after=mark)


async def _keep_pad_alive(page: PageSocket, stop: asyncio.Event, direction_deg: int) -> None:
    pad_ms = 2.0
    while not stop.is_set():
        await page.send(held(direction_deg, pad_ms=pad_ms))
        pad_ms += 50
        await asyncio.sleep(0.05)


@contextlib.asynccontextmanager
async def pad_kept_alive(page: PageSocket, direction_deg: int = 90) -> AsyncIterator[None]:
    """For the block's time, the page's steady re-send while the dead-man is held, the pad
    reporting each time."""
    stop = asyncio.Event()
    sender = asyncio.ensure_future(_keep_pad_alive(page, stop, direction_deg))
    try:
        yield
    finally:
        stop.set()
        await sender


async def test_hello_carries_the_command_table_limits_and_readings_follow(station):
    page = await PageSocket.open(station.ws_url)
    assert (
        page.hello["limits"]["mgmp"]["arguments"][0]["max"] == lookup("mgmp").arguments[0].maximum
    )
    assert page.hello["pilot_id"] is None
    reading = await page.next("telemetry", lambda m: m["sensors"] is not None)
    assert set(reading["sensors"]) == {
        "depth_cm",
        "pressure_raw",
        "leak",
        "roll_deg",
        "pitch_deg",
        "heading_deg",
    }
    assert reading["link"]["status"] == "ok"
    await page.next("heartbeat", timeout_s=3)  # every second, whatever the polls do
    await page.close()


async def test_the_stick_with_the_dead_man_moves_and_releasing_it_zeroes(station, line):
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    await page.send(RELEASED)
    await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark)
    await page.close()


async def test_the_dead_man_must_be_released_first(station, line):
    page = await pilot(station)
    mark = line.mark()
    await page.send({"type": "command", "name": "start"})
    await page.send(held(pad_ms=1.0))  # held since before this pilot took control
    await page.send({"type": "command", "name": "h+"})  # a fence: everything before it is in
    await asyncio.to_thread(line.wait_for, "#h+!", after=mark)
    assert "#th.90.60!" not in line.frames(mark)
    reading = await page.next("telemetry")
    assert reading["relay"]["status"] == "release the dead-man to arm"
    await page.close()


@pytest.mark.realtime
async def test_a_dropped_websocket_zeroes_the_thrust_within_500_ms(station, line):
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    dropped_s = time.monotonic()
    page.connection.transport.abort()  # no closing handshake: as a cable pulled
    zero = await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark)
    assert zero.at_s - dropped_s < CUT_WITHIN_S


@pytest.mark.realtime
async def test_a_silent_page_is_cut_after_300_ms_within_500_ms(station, line):
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    last_input_s = time.monotonic()  # nothing more is sent: the page froze
    zero = await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark)
    assert 0.25 < zero.at_s - last_input_s < CUT_WITHIN_S
    log = await page.next("log", lambda m: "no input from the page" in m["text"])
    assert log["level"] == "warning"
    await page.close()


@pytest.mark.realtime
async def test_a_frozen_pad_is_cut_though_the_page_keeps_sending(station, line):
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    frozen_s = time.monotonic()
    stop = asyncio.Event()

    async def frozen() -> None:  # the same pad timestamp, again and again
        while not stop.is_set():
            await page.send(held(pad_ms=1.0))
            await asyncio.sleep(0.05)

    sender = asyncio.ensure_future(frozen())
    try:
        zero = await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark)
    finally:
        stop.set()
        await sender
    assert zero.at_s - frozen_s < CUT_WITHIN_S
    log = await page.next("log", lambda m: "thrust to zero" in m["text"])
    assert "the gamepad reported nothing" in log["text"]
    await page.close()


@pytest.mark.realtime
async def test_input_that_arrives_late_is_not_relayed_though_it_keeps_arriving(station, line):
    # A network slower than the page's input (a weak Wi-Fi): every message gets through, each
    # later than the one before. Before, the stick flew on as it had been seconds ago, and the
    # dead-man's release took as long to arrive. The page stamps each input with its own clock.
    page = await pilot(station)
    await fly(page, line)

    async def send(message: dict[str, Any], late_s: float) -> None:
        sent_ms = (time.monotonic() - late_s) * 1e3
        await page.send({**message, "sent_ms": sent_ms})

    pad_ms = 10.0
    for _ in range(3):  # on time
        await send(held(pad_ms=pad_ms), late_s=0.0)
        pad_ms += 50
        await asyncio.sleep(0.05)
    mark = line.mark()
    late_from_s = time.monotonic()
    stop = asyncio.Event()

    async def late() -> None:  # the pad live, its messages arriving 600 ms late
        nonlocal pad_ms
        while not stop.is_set():
            await send(held(pad_ms=pad_ms), late_s=0.6)
            pad_ms += 50
            await asyncio.sleep(0.05)

    sender = asyncio.ensure_future(late())
    try:
        zero = await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark)
        assert zero.at_s - late_from_s < CUT_WITHIN_S
        log = await page.next("log", lambda m: "late" in m["text"])
        assert "arrives 0.6 s late" in log["text"]
        await send(RELEASED, late_s=0.6)  # released and held again, late: nothing flies
    finally:
        stop.set()
        await sender
    await send(RELEASED, late_s=0.0)  # on time again: released and held, it flies
    await send(held(pad_ms=pad_ms), late_s=0.0)
    flown = await asyncio.to_thread(line.wait_for, "#th.90.60!", after=mark)
    assert [frame for frame in line.frames(mark) if frame == "#th.90.60!"] == ["#th.90.60!"]
    assert flown.at_s > zero.at_s
    await page.close()


async def test_a_live_pad_keeps_flying_and_the_motion_is_renewed(station, line):
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    async with pad_kept_alive(page):
        renewed = await asyncio.to_thread(line.wait_for, "#th.90.60!", after=mark, timeout_s=3)
        second = await asyncio.to_thread(
            line.wait_for, "#th.90.60!", after=line.received.index(renewed) + 1, timeout_s=3
        )
    assert second.at_s > renewed.at_s
    assert "#th.90.0!" not in line.frames(mark)
    await page.close()


async def test_a_hidden_page_zeroes_the_thrust(station, line):
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    await page.send({"type": "visibility", "hidden": True})
    await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S)
    await page.send(RELEASED)  # a hidden page's input is refused, however it arrives
    assert "hidden page" in (await page.next("error"))["message"]
    await page.send({"type": "visibility", "hidden": False})
    await page.send(RELEASED)
    await page.send(held(pad_ms=9.0))
    await asyncio.to_thread(line.wait_for, "#th.90.60!", after=mark)
    await page.close()


async def test_a_second_page_cannot_command_and_taking_control_is_shown_to_both(station, line):
    first = await pilot(station)
    second = await PageSocket.open(station.ws_url)
    assert second.hello["pilot_id"] == first.id
    mark = line.mark()
    await second.send({"type": "command", "name": "start"})
    error = await second.next("error")
    assert "only the pilot" in error["message"]
    await second.send(RELEASED)
    await second.send(held())
    await second.next("error")
    await first.send({"type": "command", "name": "h-"})  # a fence
    await asyncio.to_thread(line.wait_for, "#h-!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#h-!"]

    await fly(first, line)
    mark = line.mark()
    await second.send({"type": "take_control"})
    for page in (first, second):
        control = await page.next("control", lambda m: m["pilot_id"] == second.id)
        assert "took control from" in control["text"]
    await asyncio.to_thread(line.wait_for, "#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S)
    await first.send(held(pad_ms=5.0))
    assert "only the pilot" in (await first.next("error"))["message"]
    await first.close()
    await second.close()


async def test_stop_works_from_any_page(station, line):
    first = await pilot(station)
    await fly(first, line)
    watcher = await PageSocket.open(station.ws_url)
    mark = line.mark()
    await watcher.send({"type": "stop"})
    await asyncio.to_thread(line.wait_for, "#stop!", after=mark)
    await asyncio.to_thread(line.wait_until, lambda: line.controller_locked)
    await first.close()
    await watcher.close()


async def stop_on_its_own(url: str, message: str, **options: Any) -> str:
    """Send ``message`` on a ``/stop`` WebSocket of its own; the station's answer."""
    async with connect(url, **options) as socket:
        await socket.send(message)
        return str(await asyncio.wait_for(socket.recv(), 5))


async def test_a_stop_on_a_socket_of_its_own_is_taken_once_and_checked_as_the_page_is(
    station, line
):
    page = await pilot(station)
    await fly(page, line)
    stop_url = station.ws_url[: -len("ws")] + "stop"
    mark = line.mark()
    press = json.dumps({"stop_id": "k1-1", "page_id": page.id})
    assert await stop_on_its_own(stop_url, press) == "stopped"
    await asyncio.to_thread(line.wait_for, "#stop!", after=mark)
    # The same press over the page's socket, after it: nothing more (and one log entry).
    await page.send({"type": "stop", "stop_id": "k1-1"})
    await page.send({"type": "command", "name": "h+"})  # a fence
    await asyncio.to_thread(line.wait_for, "#h+!", after=mark)
    logged = await page.next("log", lambda m: m["text"].startswith("STOP"))
    assert logged["text"] == f"STOP from {page.hello['label']}"

    def logs() -> list[str]:
        return [m["text"] for m in page.messages if m["type"] == "log"]

    await until(lambda: any(text.endswith("#h+!") for text in logs()))
    assert not [text for text in logs() if "STOP" in text]
    assert line.frames(mark, commands_only=True) == ["#stop!", "#h+!"]
    # Checked as a page's socket is: from another origin it is refused; what is not a STOP
    # is answered with what was wrong, and stops nothing.
    with pytest.raises(InvalidStatus) as refused:
        await stop_on_its_own(stop_url, press, origin="http://evil.example")
    assert refused.value.response.status_code == 403
    answer = await stop_on_its_own(stop_url, '{"stop_id": 7}')
    assert answer == "refused: stop: 'stop_id' must be a string, got 7"
    await page.close()


HOSTILE: list[str | bytes] = [
    b"\x00\x01binary",
    "not json",
    "[1, 2, 3]",
    '"a string"',
    "{}",
    '{"type": 7}',
    '{"type": "fly-away"}',
    '{"type": "command", "name": "th", "values": [90, 100]}',
    '{"type": "command", "name": "mvs", "values": [100]}',
    '{"type": "command", "name": "crcon"}',
    '{"type": "command", "name": "qd"}',
    '{"type": "command", "name": "mgmp", "values": [256]}',
    '{"type": "command", "name": "mgmp", "values": ["255"]}',
    '{"type": "command", "name": "mgmp", "values": [true]}',
    '{"type": "command", "name": "mvd"}',
    '{"type": "command", "name": "nope"}',
    '{"type": "input", "deadman": true, "direction_deg": 400, "power_percent": 50,'
    ' "vertical_percent": 0, "pad_timestamp_ms": 1}',
    '{"type": "input", "deadman": true, "direction_deg": 90, "power_percent": 1e400,'
    ' "vertical_percent": 0, "pad_timestamp_ms": 1}',
    '{"type": "input", "deadman": "yes", "direction_deg": 90, "power_percent": 50,'
    ' "vertical_percent": 0, "pad_timestamp_ms": 1}',
    '{"type": "input", "deadman": true, "direction_deg": 90, "power_percent": 50,'
    ' "vertical_percent": 0, "pad_timestamp_ms": NaN}',
    '{"type": "input", "deadman": true, "direction_deg": 90, "power_percent": 50,'
    ' "vertical_percent": 0, "source": "mind-control"}',
    '{"type": "visibility", "hidden": "maybe"}',
    '{"type": "take_control", "from": 5}',
    "[" * 5000 + "]" * 5000,
    '{"type": "stop", "padding": "' + "x" * 5000 + '"}',
]


async def test_hostile_messages_get_an_error_and_never_a_frame(station, line):
    page = await pilot(station)
    mark = line.mark()
    await page.send({"type": "command", "name": "start"})
    await page.send(RELEASED)
    await asyncio.to_thread(line.wait_for, "#start!", after=mark)
    mark = line.mark()
    for message in HOSTILE:
        await page.send(message)
        error = await page.next("error")
        assert error["message"]
    await page.send({"type": "command", "name": "h+"})  # a fence, and the server is still there
    await asyncio.to_thread(line.wait_for, "#h+!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#h+!"]
    await page.close()


def _flood(url: str, message: str, count: int) -> None:
    """Send ``message`` ``count`` times as fast as a socket takes them (until it is closed)."""
    from websockets.sync.client import connect

    with connect(url, close_timeout=0.5) as flooder, contextlib.suppress(ConnectionClosed):
        for _ in range(count):
            flooder.send(message)


@pytest.mark.realtime
async def test_a_flooding_page_is_closed_and_the_pilot_flies_on(station, line):
    # (Before, a page's queued messages were handled without a pause: a watcher sending
    # garbage held up the pilot's input long enough for the watchdog to cut it, and the
    # polls dropped to one or two a second.)
    page = await pilot(station)
    await fly(page, line)
    mark = line.mark()
    async with pad_kept_alive(page):
        await asyncio.to_thread(_flood, station.ws_url, "not json", 20_000)
        closed = await page.next("log", lambda m: "sent more than" in m["text"])
        await asyncio.sleep(0.5)  # the pilot flies on
    assert "connection is closed" in closed["text"]
    assert not [frame for frame in line.frames(mark) if frame.startswith("#th.90.0")]
    await page.close()


async def test_an_oversized_websocket_message_closes_that_socket_only(station, line):
    page = await pilot(station)
    await page.send("x" * 100_000)
    await asyncio.wait_for(page.connection.wait_closed(), 5)
    other = await PageSocket.open(station.ws_url)
    assert other.hello["pilot_id"] is None  # the pilot's socket went: nobody flies
    await other.close()


async def test_another_origin_and_another_host_are_refused(station):
    with pytest.raises(InvalidStatus) as refused:
        await PageSocket.open(station.ws_url, origin="http://evil.example")
    assert refused.value.response.status_code == 403
    request = urllib.request.Request(station.base, headers={"Host": "rebound.example:80"})
    with pytest.raises(urllib.error.HTTPError) as http:
        await asyncio.to_thread(urllib.request.urlopen, request, timeout=5)
    assert http.value.code == 403
    same = await PageSocket.open(station.ws_url, origin=station.base.rstrip("/"))
    await same.close()


async def test_beyond_loopback_the_token_is_required(line):
    with running_station(line.url, "--host", "0.0.0.0") as served:
        assert "?token=" in served.url
        token = served.url.split("?token=")[1]

        def get(url: str, **headers: str) -> int:
            request = urllib.request.Request(url, headers=headers)
            try:
                with urllib.request.urlopen(request, timeout=5) as response:
                    return int(response.status)
            except urllib.error.HTTPError as error:
                return error.code

        assert await asyncio.to_thread(get, served.base) == 403
        assert await asyncio.to_thread(get, served.base + "static/js/main.js") == 403
        assert await asyncio.to_thread(get, served.base + "?token=wrong-token") == 403
        cookie = f"rovlink-station-{served.base.rsplit(':', 1)[1].strip('/')}={token}"
        assert await asyncio.to_thread(get, served.base, Cookie=cookie) == 200
        mark = line.mark()
        for url in (served.ws_url, served.ws_url + "?token=wrong-token"):
            with pytest.raises(InvalidStatus):
                await PageSocket.open(url)
        page = await PageSocket.open(served.ws_url + f"?token={token}")
        await page.send({"type": "take_control"})
        await page.send({"type": "command", "name": "h+"})
        await asyncio.to_thread(line.wait_for, "#h+!", after=mark)
        assert line.frames(mark, commands_only=True) == ["#h+!"]
        await page.close()


async def test_the_page_redirects_a_token_url_into_a_cookie(line):
    with running_station(line.url, "--host", "0.0.0.0", "--token", "a-long-enough-token") as served:

        class Stay(urllib.request.HTTPRedirectHandler):
            def redirect_request(self, *args, **kwargs):
                return None

        opener = urllib.request.build_opener(Stay)
        with pytest.raises(urllib.error.HTTPError) as redirect:
            await asyncio.to_thread(opener.open, served.url, timeout=5)
        assert redirect.value.code == 303
        assert redirect.value.headers["Location"] == "/"
        cookie = redirect.value.headers["Set-Cookie"]
        assert "a-long-enough-token" in cookie
        assert "httponly" in cookie.lower()
        assert "samesite=strict" in cookie.lower()


async def test_a_killed_station_leaves_the_robot_to_its_own_failsafe(line):
    with running_station(line.url) as served:
        page = await pilot(served)
        await fly(page, line)
        async with pad_kept_alive(page):
            os.kill(served.process.pid, signal.SIGKILL)
            served.process.wait(timeout=5)
        # Nothing feeds the controller's link-loss watchdog (P17, 2 s): it stops the robot.
        await asyncio.to_thread(line.wait_until, lambda: line.controller_locked, 4.0)
        assert line.server.robot.controller.state().power_percent == 0


async def test_a_station_restarted_at_once_after_being_killed_locks_the_robot_it_left_moving():
    """On a serial line (a PTY here: no connection ends with the process), a station killed
    mid-dive and started again within the controller's failsafe time (P17) feeds that failsafe
    with its polls. Before, it sent no frame of its own: the robot went on at the old station's
    thrust for good, while every page showed no thrust and the motors locked after a reset."""
    line = ControllerLine(pty=True)
    try:
        assert line.pty_path is not None
        with running_station(line.pty_path) as served:
            page = await pilot(served)
            await fly(page, line)
            async with pad_kept_alive(page):
                os.kill(served.process.pid, signal.SIGKILL)
                served.process.wait(timeout=5)
        mark = line.mark()
        with running_station(line.pty_path) as restarted:
            # (The failsafe, had the restart been slow, would have locked it with no frame.)
            await asyncio.to_thread(line.wait_for, "#stop!", after=mark)
            assert line.controller_locked
            assert line.server.robot.controller.state().power_percent == 0
            watcher = await PageSocket.open(restarted.ws_url)
            assert watcher.hello["telemetry"]["commanded"]["lock"] == "locked"
            await watcher.close()
    finally:
        line.close()


@pytest.mark.parametrize(
    ("signals", "status"),
    [
        ([signal.SIGINT], 130),
        ([signal.SIGTERM], 0),
        ([signal.SIGHUP], 0),
        ([signal.SIGINT, signal.SIGHUP], 130),
        ([signal.SIGQUIT], 130),
    ],
    ids=["SIGINT", "SIGTERM", "SIGHUP", "SIGINT-then-SIGHUP", "SIGQUIT"],
)
async def test_ctrl_c_terminate_or_a_closed_terminal_sends_stop_on_the_way_out(
    line, signals, status
):
    # (Ctrl-C, then the terminal closed while the station shuts down gracefully, waiting for
    # the open page: before, SIGHUP cancelled that shutdown, and the exit status said 130.)
    with running_station(line.url) as served:
        page = await pilot(served)
        await fly(page, line)
        mark = line.mark()
        for how in signals:
            served.process.send_signal(how)
        await asyncio.to_thread(line.wait_for, "#stop!", after=mark)
        # (Ctrl-C: 130, as every command; a service stopped or a terminal closed: 0.)
        assert await asyncio.to_thread(served.process.wait, 10) == status


async def test_a_lost_robot_link_is_shown_and_disarms_the_relay(station, line):
    page = await pilot(station)
    await fly(page, line)
    line.close()  # the robot's end goes away (a USB adapter unplugged)
    alarm = await page.next("log", lambda m: m["text"].startswith("link lost"))
    assert alarm["level"] == "alarm"
    reading = await page.next("telemetry", lambda m: not m["link"]["connected"], timeout_s=10)
    assert reading["relay"]["armed"] is False
    assert "link was lost" in reading["relay"]["status"]
    await page.close()


@pytest.mark.realtime
async def test_a_controller_that_hears_but_stops_answering_is_stopped_and_the_pilot_told(
    station, line
):
    """Its TX wire broke: the controller obeys every frame and answers none. Flying on, the
    pilot would fly blind (old depth, leak and attitude on the screen): the station stops it
    within its silence limit, and says why."""
    page = await pilot(station)
    await fly(page, line)
    async with pad_kept_alive(page):
        mark = line.mark()
        silent_at_s = time.monotonic()
        line.stop_replying()
        stop = await asyncio.to_thread(line.wait_for, "#stop!", after=mark, timeout_s=5.0)
        alarm = await page.next(
            "log", lambda m: m["text"].startswith("the controller stopped answering")
        )
        reading = await page.next(
            "telemetry", lambda m: m["relay"]["status"] == TELEMETRY_LOST_STATUS
        )
    assert stop.at_s - silent_at_s < TELEMETRY_LOST_S + CUT_WITHIN_S
    assert line.controller_locked  # it heard the #stop!, and obeys it: every output at zero
    assert alarm["level"] == "alarm"
    assert "depth, leak and attitude" in alarm["text"]
    assert reading["relay"]["armed"] is False
    # The pad held all along flew nothing after the #stop!: nothing is relayed, blind.
    after_stop = line.frames(mark, commands_only=True)
    after_stop = after_stop[after_stop.index("#stop!") :]
    assert not [f for f in after_stop if f.startswith(("#th.", "#mvs.", "#start"))], after_stop
    await page.close()


def _ipv6_loopback() -> bool:
    try:
        with socket.socket(socket.AF_INET6) as probe:
            probe.bind(("::1", 0))
    except OSError:
        return False
    return True


@pytest.mark.skipif(not _ipv6_loopback(), reason="no IPv6 loopback here")
async def test_an_ipv6_host_in_brackets_is_served(line):
    with running_station(line.url, "--host", "[::1]") as served:
        assert served.base.startswith("http://[::1]:")
        page = await PageSocket.open(served.ws_url)
        assert page.hello["pilot_id"] is None
        await page.close()


async def test_the_pilot_leaving_while_the_robot_link_is_down_is_shown_to_every_page():
    port = FakeControllerServer()  # a robot whose adapter can be pulled out and plugged back
    try:
        with running_station(port.url) as served:
            page = await pilot(served)
            watcher = await PageSocket.open(served.ws_url)
            await page.send({"type": "command", "name": "start"})
            await page.send(RELEASED)
            await page.send(held(pad_ms=1.0))
            flown = await asyncio.to_thread(
                port.fakes[0].wait_for, lambda fake: "#th.90.60!" in fake.frames()
            )
            assert flown
            port.refuse = True
            port.fakes[0].close()
            await watcher.next("log", lambda m: m["text"].startswith("link lost"))
            await page.close()
            # (Before, the cut's zero thrust raised on the lost link out of the closed page's
            # end, and no page was told that nobody had control.)
            await watcher.next("control", lambda m: m["pilot_id"] is None)
            await watcher.send({"type": "take_control"})
            await watcher.next("control", lambda m: m["pilot_id"] == watcher.id)
            port.refuse = False
            await watcher.next("log", lambda m: "link reconnected" in m["text"], timeout_s=10)
            assert served.process.poll() is None
            await watcher.close()
    finally:
        port.close()
