"""The station's hub in-process, on the simulated robot and a simulated clock: the orderings a
socket test cannot force (a held frame's timer against a cut) and what the event log says."""

from __future__ import annotations

import asyncio
import contextlib
import errno
import json
import threading
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

import rovlink.aio
from rovlink.client.events import BytesSent, ClientEvent, LinkState
from rovlink.piloting import LockState, TrackedClient
from rovlink.recorder.entries import Entry
from rovlink.recorder.formats import open_sink
from rovlink.recorder.sink import Sink
from rovlink.station.hub import (
    CLOSING_STATUS,
    MESSAGE_BURST,
    MESSAGES_PER_S,
    TELEMETRY_LOST_S,
    TELEMETRY_LOST_STATUS,
    Peer,
    Station,
)
from rovlink.station.recording import StationRecordings


@dataclass
class Clock:
    """The station's clock, moved by hand."""

    now_s: float = 100.0

    def __call__(self) -> float:
        return self.now_s


@dataclass
class Hub:
    """A station on ``sim://`` with every frame it writes (keep-alives and polls left out)."""

    station: Station
    clock: Clock
    sent: list[str] = field(default_factory=list)

    def on_event(self, event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and not event.data.startswith(b"#q"):
            self.sent.append(event.data.decode())

    async def send(self, peer: Peer, message: dict[str, Any]) -> None:
        await self.station.handle(peer, json.dumps(message))

    async def pilot(self) -> Peer:
        peer = self.station.join("test")
        await self.send(peer, {"type": "take_control"})
        assert self.station.pilot is peer
        return peer

    async def settled(self) -> None:
        """Every frame task the station started has run."""
        while self.station._sending:
            await asyncio.gather(*self.station._sending)

    def warnings(self) -> list[str]:
        return [
            entry["text"] for entry in self.station._log if entry["level"] in ("warning", "alarm")
        ]


@contextlib.asynccontextmanager
async def station_on_sim(recordings_in: Path | None = None) -> AsyncIterator[Hub]:
    """A station on ``sim://``; with ``recordings_in``, its record button writes there."""
    client = await rovlink.aio.connect("sim://")
    clock = Clock()
    recordings = (
        None
        if recordings_in is None
        else StationRecordings(
            recordings_in, url="sim://", checksum=False, algorithm="crc8", clock=clock
        )
    )
    station = Station(
        TrackedClient(client, algorithm="crc8"),
        description="sim://",
        clock=clock,
        recordings=recordings,
    )
    made = Hub(station, clock)
    client.subscribe(made.on_event)
    try:
        yield made
    finally:
        await client.close()


@pytest.fixture
async def hub() -> AsyncIterator[Hub]:
    async with station_on_sim() as made:
        yield made


def keys(deadman: bool, direction_deg: int = 90, power_percent: int = 0) -> dict[str, Any]:
    return {
        "type": "input",
        "deadman": deadman,
        "direction_deg": direction_deg,
        "power_percent": power_percent,
        "vertical_percent": 0,
        "source": "keyboard",
    }


def pad(deadman: bool, pad_ms: float, power_percent: int = 50) -> dict[str, Any]:
    return {**keys(deadman, 45, power_percent), "source": "gamepad", "pad_timestamp_ms": pad_ms}


def thrust(frames: list[str]) -> list[str]:
    return [frame for frame in frames if frame.startswith("#th.")]


async def held_back(hub: Hub) -> Peer:
    """A pilot flying at 40 % whose change to 80 % the relay holds back (``min_interval_s``);
    the flush timer is cancelled, so the test fires it when it wants."""
    peer = await hub.pilot()
    await hub.send(peer, {"type": "command", "name": "start"})
    await hub.send(peer, keys(False))
    await hub.send(peer, keys(True, power_percent=40))
    hub.clock.now_s += 0.005
    await hub.send(peer, keys(True, power_percent=80))
    timer = hub.station._flush_timer
    assert timer is not None
    assert hub.station.relay.due_s is not None
    timer.cancel()
    hub.station._flush_timer = None
    hub.clock.now_s += 0.05  # the held change is due
    hub.sent.clear()
    return peer


async def test_a_held_frame_whose_timer_fired_does_not_follow_the_pilots_leaving(hub):
    peer = await held_back(hub)
    hub.station._flush_due()  # the timer's callback: the flush task is created ...
    await hub.station.leave(peer)  # ... and the page's disconnect is handled before it runs
    await hub.settled()
    assert thrust(hub.sent) == ["#th.90.0!"]  # the cut, and nothing after it
    assert hub.station.tracked.commanded.power_percent == 0


async def test_a_held_frame_whose_timer_fired_does_not_follow_a_take_over(hub):
    await held_back(hub)
    hub.station._flush_due()
    await hub.send(hub.station.join("other"), {"type": "take_control"})
    await hub.settled()
    assert thrust(hub.sent) == ["#th.90.0!"]  # the cut, and nothing after it
    assert hub.station.tracked.commanded.power_percent == 0


async def test_a_held_frame_whose_timer_fired_does_not_follow_a_stop(hub):
    peer = await held_back(hub)
    hub.station._flush_due()  # the motion is on its way ...
    await hub.send(hub.station.join("other"), {"type": "stop"})  # ... when a STOP comes
    await hub.settled()
    assert hub.sent == ["#stop!"]  # nothing after it: no #th.90.80!
    assert hub.station.tracked.commanded.lock is LockState.LOCKED
    await hub.send(peer, keys(True, power_percent=80))  # the stick still held: cut, disarmed
    assert thrust(hub.sent) == []


async def test_a_held_frame_goes_out_when_due(hub):
    await held_back(hub)
    hub.station._flush_due()
    await hub.settled()
    assert hub.sent == ["#th.90.80!"]


async def test_a_frozen_pad_seen_on_an_input_message_is_logged(hub):
    peer = await hub.pilot()
    await hub.send(peer, {"type": "command", "name": "start"})
    await hub.send(peer, pad(False, 1.0))
    await hub.send(peer, pad(True, 2.0))
    assert hub.station.relay.moving
    hub.sent.clear()
    for _ in range(8):  # the page keeps sending, the pad's timestamp stands still
        hub.clock.now_s += 0.05
        await hub.send(peer, pad(True, 2.0))
    assert hub.sent[0] == "#th.45.0!"
    assert hub.warnings() == ["thrust to zero: the gamepad reported nothing for 300 ms"]


async def test_a_cut_after_stop_sends_zero_thrust_without_a_warning(hub):
    peer = await hub.pilot()
    await hub.send(peer, {"type": "command", "name": "start"})
    await hub.send(peer, {"type": "stop"})
    hub.sent.clear()
    await hub.station.leave(peer)  # the pilot's page closed while the robot is locked
    assert hub.sent == ["#th.0.0!", "#mvs.+0!"]  # (no mode sent: vertical zeroed too)
    assert hub.warnings() == [f"STOP from {peer.label}"]  # no "dropped while locked" warnings


class FillingDisk:
    """Sinks that fail as a full disk does (ENOSPC) once :attr:`full` is set."""

    def __init__(self) -> None:
        self.full = threading.Event()

    def sink(self, real: Sink) -> Sink:
        disk = self

        class Filling:
            unit = real.unit

            def write(self, entry: Entry) -> None:
                disk.check()
                real.write(entry)

            def flush(self) -> None:
                disk.check()
                real.flush()

            def close(self) -> None:
                real.close()

            def size_bytes(self) -> int:
                return real.size_bytes()

            def held(self) -> int:
                return real.held()

        return Filling()

    def check(self) -> None:
        if self.full.is_set():
            raise OSError(errno.ENOSPC, "No space left on device")


async def until(condition: Callable[[], bool], timeout_s: float = 5.0) -> None:
    """Wait for ``condition`` between turns of the event loop; fail after ``timeout_s``."""
    deadline_s = asyncio.get_running_loop().time() + timeout_s
    while not condition():
        assert asyncio.get_running_loop().time() < deadline_s, "condition not met in time"
        await asyncio.sleep(0.01)


async def test_a_recording_that_fills_the_disk_ends_at_once_with_its_true_length(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    disk = FillingDisk()
    monkeypatch.setattr(
        "rovlink.recorder.recorder.open_sink", lambda path: disk.sink(open_sink(path))
    )
    async with station_on_sim(tmp_path) as hub:
        recordings = hub.station.recordings
        assert recordings is not None
        peer = await hub.pilot()
        await hub.send(peer, {"type": "record_start"})
        assert recordings.active
        hub.clock.now_s += 4.0
        disk.full.set()
        await hub.send(peer, {"type": "command", "name": "h+"})  # something to write
        await until(lambda: not recordings.active)
        hub.clock.now_s += 4.0  # the pilot notices later: the recording ended at 4 s
        state = recordings.state()
        assert state["active"] is False
        assert state["elapsed_s"] is None
        assert "No space left on device" in state["failure"]
        assert [(item["duration_s"], item["failed"]) for item in state["finished"]] == [(4.0, True)]
        assert any("No space left" in text for text in hub.warnings())  # the alarm, at once
        told = [m for m in drain(peer) if m["type"] == "recording"]
        assert told[-1]["active"] is False

        await hub.send(peer, {"type": "record_stop"})
        assert "not recording" in [m for m in drain(peer) if m["type"] == "error"][-1]["message"]
        disk.full.clear()
        await hub.send(peer, {"type": "record_start"})
        assert recordings.state()["failure"] is None  # a new recording: the old failure goes
        await hub.send(peer, {"type": "record_stop"})


def drain(peer: Peer) -> list[dict[str, Any]]:
    messages = []
    while not peer.outbox.empty():
        messages.append(peer.outbox.get_nowait())
    return messages


async def test_a_page_that_floods_is_told_to_go_and_a_steady_one_never(hub):
    flooder = hub.station.join("flooder")
    steady = await hub.pilot()
    answers = [await hub.station.handle(flooder, "not json") for _ in range(int(MESSAGE_BURST))]
    assert all(answers)  # a burst, as a network that stalled delivers, is taken
    assert await hub.station.handle(flooder, '{"type": "stop"}') is False
    assert f"{flooder.label} sent more than" in hub.warnings()[-1]
    assert hub.sent == []  # the message over the allowance was not acted on
    for _ in range(3 * int(MESSAGES_PER_S)):  # three seconds at the allowance, and more
        hub.clock.now_s += 1 / MESSAGES_PER_S
        assert await hub.station.handle(steady, json.dumps(keys(False)))


async def test_every_page_gets_a_heartbeat_whatever_the_polls_do(
    hub, monkeypatch: pytest.MonkeyPatch
):
    monkeypatch.setattr("rovlink.station.hub.HEARTBEAT_S", 0.01)
    peer = hub.station.join("page")
    drain(peer)
    beating = asyncio.ensure_future(hub.station._beat())
    try:
        await until(lambda: any(m["type"] == "heartbeat" for m in drain(peer)))
    finally:
        beating.cancel()
    assert hub.station._hello(peer)["heartbeat_ms"] == 10.0  # the page knows what to expect


async def test_a_failed_poll_leaves_no_reading_current_and_a_gap_in_the_charts(hub):
    hub.station._reading(await hub.station.tracked.sensors())
    assert hub.station.latest is not None
    hub.station._no_reading()
    assert hub.station.latest is None  # a page opened now does not get the old reading
    peer = hub.station.join("late")
    hello = drain(peer)[0]
    assert hello["telemetry"]["sensors"] is None
    assert [row[1] for row in hello["history"]][-1] is None  # the charts break the line there


async def test_a_reopened_link_forgets_the_lock_as_last_sent(hub):
    peer = await hub.pilot()
    await hub.send(peer, {"type": "command", "name": "start"})
    await hub.send(peer, {"type": "command", "name": "mvdirect", "values": [1]})
    await hub.send(peer, keys(False))
    await hub.send(peer, {**keys(True, power_percent=60), "vertical_percent": 30})
    commanded = hub.station.tracked.commanded
    assert (commanded.power_percent, commanded.vertical_thrust_percent) == (60, 30)
    hub.station._on_client_event(LinkState(at_s=1.0, state="lost", detail="unplugged"))
    hub.station._on_client_event(LinkState(at_s=2.0, state="reconnected", detail="ttyUSB0"))
    # The driver's first frames on the reopened link were zero thrust: at rest as last sent
    # (before, "90° at 60 %" stayed on every page as last sent until the pilot let go).
    assert (commanded.power_percent, commanded.vertical_thrust_percent) == (0, 0)
    assert commanded.lock is LockState.UNKNOWN  # the controller may be another boot: locked
    assert "reopened" in hub.station._telemetry(None)["commanded"]["lock_unknown_because"]
    assert "unlock (#start!) to fly again" in hub.warnings()[-1]


async def test_a_late_poll_is_not_followed_by_another_at_once(hub, monkeypatch: pytest.MonkeyPatch):
    # (Before, the poll after a late one went at once: two readings in the same millisecond,
    # one time twice in the charts; a flaky page test caught it.) Timed from the late reply to
    # the next poll's start, which a loaded machine can only delay: the gaps between on-time
    # polls depend on how late the event loop wakes.
    asked_at: list[float] = []
    answered_at: list[float] = []
    read = hub.station.tracked.sensors

    async def slow_second_reply() -> Any:
        asked_at.append(asyncio.get_running_loop().time())
        if len(asked_at) == 2:
            await asyncio.sleep(0.25)  # a slow reply: the next poll is due already
        reading = await read()
        answered_at.append(asyncio.get_running_loop().time())
        return reading

    monkeypatch.setattr(hub.station.tracked, "sensors", slow_second_reply)
    polling = asyncio.ensure_future(hub.station._poll())
    try:
        await until(lambda: len(asked_at) >= 3)
    finally:
        polling.cancel()
    after_the_late_reply_s = asked_at[2] - answered_at[1]
    assert after_the_late_reply_s > 0.5 / hub.station.rate_hz, (asked_at, answered_at)


def lateness_over(peer: Peer, seconds: float, page_rate: float, every_s: float = 0.05) -> float:
    """The most ``peer.lateness_s`` says over ``seconds`` of inputs every ``every_s``, each
    sent at the page's clock running ``page_rate`` times the station's."""
    most = 0.0
    for step in range(int(seconds / every_s)):
        now_s = step * every_s
        most = max(most, peer.lateness_s(now_s * page_rate * 1e3, now_s))
    return most


def test_a_page_clock_that_drifts_is_not_taken_for_a_slow_network():
    # Two computers' clocks: the page's 0.05 % slow, for two hours. Without an allowance, its
    # input would have been measured 3.6 s late, and cut as stale, after two hours.
    assert lateness_over(Peer("p1", "browser 1"), 7200.0, page_rate=0.9995) < 0.05
    # A network that holds the input back makes it later far faster: 10 % a second.
    assert lateness_over(Peer("p2", "browser 2"), 5.0, page_rate=0.9) > 0.3


async def test_a_closing_station_stops_the_robot_and_then_takes_only_stop(hub):
    pilot = await hub.pilot()
    await hub.send(pilot, {"type": "command", "name": "start"})
    await hub.send(pilot, keys(False))
    await hub.send(pilot, keys(True, power_percent=50))
    await hub.station.stop_first()
    assert hub.sent[-2:] == ["#th.90.50!", "#stop!"]  # #stop! first: it zeroes every output
    sent = len(hub.sent)
    # Nothing unlocks or flies it again while the pages' connections are being closed.
    for message in (
        keys(False),
        keys(True, power_percent=50),
        {"type": "command", "name": "start"},
        {"type": "take_control"},
    ):
        await hub.send(pilot, message)
    errors = [m["message"] for m in drain(pilot) if m["type"] == "error"]
    assert errors == ["the station is closing: only STOP is taken"] * 4
    await hub.send(pilot, {"type": "stop"})
    await hub.station.leave(pilot)
    await hub.station.shutdown()
    # The STOP only: locked, neither the pilot leaving nor the shutdown sends another frame.
    assert hub.sent[sent:] == ["#stop!"]


async def test_a_closing_station_shows_every_page_the_robot_stopped(hub):
    pilot = await hub.pilot()
    await hub.send(pilot, {"type": "command", "name": "start"})
    await hub.send(pilot, keys(False))
    await hub.send(pilot, keys(True, power_percent=50))
    drain(pilot)
    await hub.station.stop_first()
    # The polls stop while the pages are closed: the state after the #stop! is sent at once.
    # Before, the pages kept "unlocked", "flying" and the thrust of the last poll for good.
    telemetry = [m for m in drain(pilot) if m["type"] == "telemetry"]
    assert telemetry, "no state after the station's #stop!"
    last = telemetry[-1]
    assert last["commanded"]["lock"] == "locked"
    assert last["commanded"]["power_percent"] == 0
    assert not last["relay"]["armed"]
    assert last["relay"]["status"] == CLOSING_STATUS


async def test_the_pilot_is_told_when_the_controller_drops_its_command(hub):
    pilot = await hub.pilot()
    await hub.send(pilot, {"type": "command", "name": "stop"})
    drain(pilot)
    # Claw open while locked: sent (the station says what it sent), and dropped by the
    # controller (P7). Before, only the event log said so, far from the button pressed.
    await hub.send(pilot, {"type": "command", "name": "h+"})
    assert hub.sent[-1] == "#h+!"
    errors = [m["message"] for m in drain(pilot) if m["type"] == "error"]
    assert errors == [
        "#h+!: the controller drops h+ while motion is locked (as last sent): send start first"
    ]
    await hub.send(pilot, {"type": "command", "name": "start"})
    await hub.send(pilot, {"type": "command", "name": "h+"})
    assert [m for m in drain(pilot) if m["type"] == "error"] == []


async def test_a_command_that_arrives_seconds_late_is_not_sent(hub):
    pilot = await hub.pilot()
    await hub.send(pilot, {**keys(False), "sent_ms": 1000.0})  # on time: the fastest
    hub.clock.now_s += 0.5
    await hub.send(pilot, {"type": "command", "name": "start", "sent_ms": 1500.0})
    assert hub.sent[-1] == "#start!"
    # A network slower than the page: Claw open, asked for at 1.6 s, arrives 3.9 s late. Sent
    # then, it would act long after it was asked for; before, it was.
    hub.clock.now_s += 4.0
    await hub.send(pilot, {"type": "command", "name": "h+", "sent_ms": 1600.0})
    errors = [m["message"] for m in drain(pilot) if m["type"] == "error"]
    assert errors == ["#h+: arrived 3.9 s late (a slow network?): not sent; ask again"]
    assert hub.sent[-1] == "#start!"
    # On time again (the network caught up): sent.
    await hub.send(pilot, {"type": "command", "name": "h+", "sent_ms": 5600.0})
    assert hub.sent[-1] == "#h+!"


async def test_a_controller_silent_past_the_limit_is_stopped_and_flies_again_only_when_answering(
    hub,
):
    """The controller hears but does not answer (the socket test shows it end to end): past the
    limit, #stop!, and the pilot's input is not relayed, nor #start! sent, while it is silent;
    answering again, it is unlocked and the dead-man released and pressed before anything
    moves."""
    station, health = hub.station, hub.station.tracked.health
    peer = await hub.pilot()
    await hub.send(peer, {"type": "command", "name": "start"})
    await hub.send(peer, keys(False))
    await hub.send(peer, keys(True, power_percent=60))
    assert hub.sent[-1] == "#th.90.60!"
    quiet_from_s = station.tracked.now_s() - (TELEMETRY_LOST_S - 0.5)
    health.last_reply_at_s = station._answers_expected_from_s = quiet_from_s
    await station._check_replies()
    assert not station.telemetry_lost  # not yet
    health.last_reply_at_s = station._answers_expected_from_s = quiet_from_s - 0.6
    await station._check_replies()
    assert station.telemetry_lost
    assert hub.sent[-1] == "#stop!"
    assert "stopped answering" in hub.warnings()[-1]
    assert station._telemetry(None)["relay"]["status"] == TELEMETRY_LOST_STATUS
    sent = len(hub.sent)
    await hub.send(peer, keys(False))
    await hub.send(peer, keys(True, power_percent=60))
    await hub.send(peer, {"type": "command", "name": "start"})
    assert hub.sent[sent:] == []  # flying blind is not taken up again
    assert "not answering" in drain(peer)[-1]["message"]
    health.record_reply(0.01, station.tracked.now_s())
    await station._check_replies()
    assert not station.telemetry_lost
    assert "answers again" in hub.warnings()[-1]
    await hub.send(peer, {"type": "command", "name": "start"})
    await hub.send(peer, keys(True, power_percent=60))  # held through the silence: nothing
    assert hub.sent[sent:] == ["#start!"]
    await hub.send(peer, keys(False))
    await hub.send(peer, keys(True, power_percent=60))
    assert hub.sent[-1] == "#th.90.60!"
