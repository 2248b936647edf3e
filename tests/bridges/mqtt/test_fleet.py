"""``rovlink fleet``: the view of every robot, and the command against a real broker."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import pytest

from rovlink.bridges.mqtt.fleet_view import SILENT_AFTER_S, FleetView
from tests.bridges.mqtt.broker import Mosquitto
from tests.bridges.mqtt.rig import bridged_robot, subscriber
from tests.cli.conftest import RunCli

_SRC = str(Path(__file__).resolve().parents[3] / "src")


def test_the_view_follows_state_telemetry_and_events():
    view = FleetView()
    view.apply(
        "rovlink/a/state", b'{"online": true, "lock": "unlocked", "link": {"status": "ok"}}', 0.0
    )
    view.apply("rovlink/a/telemetry", b'{"depth_cm": 250, "leak": false}', 0.5)
    view.apply("rovlink/a/events", b'{"event": "leak", "detail": "the leak sensor fired"}', 1.0)
    view.apply("rovlink/b/state", b'{"online": false, "reason": "bridge connection lost"}', 1.0)
    a, b = view.rows()
    assert (a.robot, a.depth_cm, a.leak, a.lock, a.link) == ("a", 250, True, "unlocked", "ok")
    assert a.last_event == "leak: the leak sensor fired"
    assert a.presence(1.0 + SILENT_AFTER_S + 0.1) == "silent"
    assert (b.presence(1.0), b.offline_reason) == ("offline", "bridge connection lost")


@pytest.mark.parametrize(
    ("topic", "payload"),
    [
        ("rovlink/a/state", b"\xff"),
        ("rovlink/a/state", b"[1, 2]"),
        ("rovlink/a/cmd", b'{"command": "stop"}'),
        ("other/a/state", b'{"online": true}'),
        ("rovlink/a", b'{"online": true}'),
        ("rovlink/a/state", b"[" * 100_000),  # deeper than the parser goes: RecursionError
        ("rovlink/a/state", b'{"online": true, "depth_cm": ' + b"1" * 5000 + b"}"),  # too many
    ],
)
def test_what_is_not_a_bridges_message_is_ignored(topic: str, payload: bytes):
    view = FleetView()
    assert not view.apply(topic, payload, 0.0)
    assert view.rows() == []
    assert view.ignored == 1


@pytest.mark.parametrize(
    "payload",
    [
        b'{"online": "false", "reason": "a string"}',
        b'{"online": 1}',
        b'{"online": null}',
        b'{"reason": "no online at all"}',
    ],
)
def test_a_state_whose_online_is_not_true_or_false_is_shown_malformed(payload: bytes):
    view = FleetView()
    view.apply("rovlink/a/state", b'{"online": true}', 0.0)
    view.apply("rovlink/a/state", payload, 0.1)
    view.apply("rovlink/a/telemetry", b'{"depth_cm": 120, "leak": false}', 0.2)
    (row,) = view.rows()
    assert row.presence(0.3) == "malformed"
    assert row.state_problem is not None
    assert '"online"' in row.state_problem
    view.apply("rovlink/a/state", b'{"online": false, "reason": "bridge stopped"}', 0.4)
    assert row.presence(0.5) == "offline"


def test_strange_values_do_not_break_a_row():
    view = FleetView()
    view.apply("rovlink/a/telemetry", b'{"depth_cm": "deep", "leak": 0}', 0.0)
    view.apply("rovlink/a/state", b'{"online": true, "lock": 5, "link": "ok"}', 0.0)
    (row,) = view.rows()
    assert (row.depth_cm, row.lock, row.link, row.presence(0.0)) == (None, None, None, "online")


@pytest.mark.integration
async def test_fleet_lists_every_robot_with_the_offline_one(broker: Mosquitto):
    async with contextlib.AsyncExitStack() as stack:
        for robot in ("r1", "r2"):
            await stack.enter_async_context(bridged_robot(broker, robot))
        async with subscriber(broker, "rovlink/gone/state") as watcher:
            async with bridged_robot(broker, "gone"):
                await watcher.wait_for("rovlink/gone/state", lambda s: s["online"])
            await watcher.wait_for("rovlink/gone/state", lambda s: not s["online"])
        environment = dict(
            os.environ,
            PYTHONPATH=_SRC + os.pathsep + os.environ.get("PYTHONPATH", ""),
            COLUMNS="160",
        )
        process = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "rovlink", "fleet", "--broker", broker.url, "--snapshot", "1.5",
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
            env=environment,
        )  # fmt: skip
        out, err = await asyncio.wait_for(process.communicate(), 30)
    assert process.returncode == 0, err.decode()
    lines = out.decode().splitlines()
    row = {
        name: next(line for line in lines if f" {name} " in line) for name in ("r1", "r2", "gone")
    }
    assert "online" in row["r1"]
    assert "online" in row["r2"]
    assert " cm" in row["r1"]
    assert "offline" in row["gone"]
    assert "bridge stopped" in row["gone"]


def test_the_table_shows_each_robot_in_words():
    from rich.console import Console

    from rovlink.cli.fleet import fleet_table

    view = FleetView()
    view.apply("rovlink/a/telemetry", b'{"depth_cm": 120, "leak": true}', 0.0)
    view.apply("rovlink/b/state", b'{"online": false, "reason": "bridge connection lost"}', 0.0)
    console = Console(width=160, record=True)
    console.print(fleet_table(view, now_s=1.0))
    text = console.export_text()
    row_a = next(line for line in text.splitlines() if " a " in line)
    row_b = next(line for line in text.splitlines() if " b " in line)
    assert "online" in row_a
    assert "120 cm" in row_a
    assert "LEAK" in row_a
    assert "offline" in row_b
    assert "bridge connection lost" in row_b
    empty = Console(width=160, record=True)
    empty.print(fleet_table(FleetView(), now_s=0.0))
    assert "no robot has published yet" in empty.export_text()


@pytest.mark.parametrize("width", [40, 60])
def test_a_narrow_terminal_keeps_each_robot_and_its_presence_whole(width: int) -> None:
    # Before, every column shrank alike: on 40 columns the rows read "r… │ o… │ d…", no robot
    # and no presence to be made out. The least needed columns now give way, and say so.
    from rich.console import Console

    from rovlink.cli.fleet import fleet_table

    view = FleetView()
    view.apply("rovlink/rov-alpha/state", b'{"online": true, "lock": "unlocked"}', 0.0)
    view.apply("rovlink/rov-alpha/telemetry", b'{"depth_cm": 120, "leak": true}', 0.0)
    view.apply("rovlink/rov-beta/state", b'{"online": false, "reason": "bridge stopped"}', 0.0)
    console = Console(width=width, record=True)
    console.print(fleet_table(view, now_s=1.0, width=width))
    text = console.export_text()
    assert "…" not in text
    lines = text.splitlines()
    assert all(len(line) <= width for line in lines)
    row_alpha = next(line for line in lines if " rov-alpha " in line)
    row_beta = next(line for line in lines if " rov-beta " in line)
    assert "online" in row_alpha
    assert "LEAK" in row_alpha
    assert "offline" in row_beta
    assert "widen the terminal" in " ".join(text.split())


def test_text_from_the_broker_is_shown_as_text_never_as_markup_or_terminal_codes():
    from rich.console import Console

    from rovlink.cli.fleet import fleet_table

    view = FleetView()
    view.apply(
        "rovlink/[b]x/state", b'{"online": true, "lock": "[red]", "link": {"status": "[/]"}}', 0
    )
    view.apply("rovlink/[b]x/events", b'{"event": "[/b]", "detail": "\\u001b[2J"}', 0)
    view.apply("rovlink/j2/state", b'{"online": false, "reason": "[/]"}', 0)
    view.apply("rovlink/j3/state", b'{"online": "false", "reason": "[bold]x"}', 0)
    console = Console(width=160, record=True)
    console.print(fleet_table(view, now_s=1.0))
    lines = console.export_text().splitlines()
    row_x = next(line for line in lines if " [b]x " in line)
    assert "[red]" in row_x
    assert "[/]" in row_x
    assert "[/b]: \\x1b[2J" in row_x
    assert "\x1b" not in console.export_text()
    assert "[/]" in next(line for line in lines if " j2 " in line)
    assert "malformed" in next(line for line in lines if " j3 " in line)


@pytest.mark.integration
async def test_fleet_prints_markup_like_retained_states_as_they_are(broker: Mosquitto):
    retained = {
        "rovlink/j2/state": '{"online": false, "reason": "[/]"}',
        "rovlink/j3/state": '{"online": "false", "reason": "[bold]x"}',
        # A lone surrogate: printing it ended the table (UnicodeEncodeError).
        "rovlink/j4/state": '{"online": false, "reason": "x\\ud800y"}',
    }
    lines = await _snapshot_after_retaining(broker, retained)
    j2 = next(line for line in lines if " j2 " in line)
    assert "offline" in j2
    assert "[/]" in j2
    j3 = next(line for line in lines if " j3 " in line)
    assert "malformed" in j3
    assert " online " not in j3  # (the problem quotes "online")
    j4 = next(line for line in lines if " j4 " in line)
    assert "x\\ud800y" in j4


@pytest.mark.integration
async def test_fleet_lists_the_robots_after_a_state_it_cannot_parse(broker: Mosquitto):
    # Before, a retained state nested deeper than the JSON parser goes ended the live table
    # (RecursionError) at every start, and left a snapshot without the robots that came after.
    retained: dict[str, str | bytes] = {
        "rovlink/bad/state": b"[" * 100_000,
        "rovlink/huge/state": b'{"online": true, "depth_cm": ' + b"1" * 5000 + b"}",
        "rovlink/good/state": b'{"online": false, "reason": "bridge stopped"}',
    }
    lines = await _snapshot_after_retaining(broker, retained)
    good = next(line for line in lines if " good " in line)
    assert "offline" in good
    assert not any(" bad " in line or " huge " in line for line in lines)


@pytest.mark.integration
async def test_fleet_marks_a_robot_whose_bridge_drives_the_simulator(broker: Mosquitto):
    # A bridge started without its URL serves rovlink's simulator: before, it stood in the
    # table as one more robot, under a real robot's id.
    retained = {
        "rovlink/rov-1/state": '{"online": true, "simulated": true}',
        "rovlink/rov-2/state": '{"online": true, "simulated": false}',
    }
    lines = await _snapshot_after_retaining(broker, retained)
    assert any(" rov-1 (simulated) " in line for line in lines), lines
    rov_2 = next(line for line in lines if " rov-2 " in line)
    assert "simulated" not in rov_2


async def _snapshot_after_retaining(
    broker: Mosquitto, retained: Mapping[str, str | bytes]
) -> list[str]:
    """The lines of ``rovlink fleet --snapshot 1`` run after ``retained`` was published so."""
    from paho.mqtt import publish

    for topic, payload in retained.items():
        await asyncio.to_thread(
            publish.single, topic, payload, qos=1, retain=True, port=broker.port
        )
    environment = dict(
        os.environ, PYTHONPATH=_SRC + os.pathsep + os.environ.get("PYTHONPATH", ""), COLUMNS="160"
    )
    process = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "rovlink", "fleet", "--broker", broker.url, "--snapshot", "1",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
        env=environment,
    )  # fmt: skip
    out, err = await asyncio.wait_for(process.communicate(), 30)
    assert process.returncode == 0, err.decode()
    return out.decode().splitlines()


@pytest.mark.integration
def test_the_live_table_rides_out_a_broker_restart(broker: Mosquitto) -> None:
    # Before, the live table ended with status 1 ("Disconnected during message iteration") as
    # the broker stopped, where the bridges it watches reconnect: a restarted broker left the
    # operator with no table. It now says the broker is lost and picks up where it left off.
    from paho.mqtt import publish

    from tests.terminals import Terminal

    def retain(robot: str) -> None:
        topic, state = f"rovlink/{robot}/state", '{"online": true, "lock": "locked"}'
        publish.single(topic, state, qos=1, retain=True, port=broker.port)

    retain("r1")
    terminal = Terminal("fleet", "--broker", broker.url, size=(120, 30))
    try:
        assert terminal.wait_shown(b" r1 ")
        broker.stop()
        assert terminal.wait_shown(b"reconnecting"), terminal.shown.decode(errors="replace")
        assert terminal.process.poll() is None
        broker.start()
        retain("r2")
        assert terminal.wait_shown(b" r2 "), terminal.shown.decode(errors="replace")
        assert terminal.process.poll() is None
    finally:
        terminal.close()


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.realtime
def test_the_live_table_says_so_when_the_broker_goes_silent(broker: Mosquitto) -> None:
    # A broker that answers nothing any more (its network gone, its host stalled) was noticed
    # only by paho-mqtt's default keep-alive, 60 s, a minute and more with no word in the
    # caption; the bridges notice within 15 s (their keep-alive: 10 s), and so does the table.
    from tests.terminals import Terminal

    terminal = Terminal("fleet", "--broker", broker.url)
    try:
        assert terminal.wait_shown(b"no robot has published yet")
        with broker.stalled():
            assert terminal.wait_shown(b"reconnecting", timeout_s=30.0), terminal.shown.decode(
                errors="replace"
            )
    finally:
        terminal.close()


@pytest.mark.integration
@pytest.mark.parametrize(
    ("how", "status", "last_line"),
    [
        (signal.SIGTERM, 0, "rovlink fleet stopped"),
        (signal.SIGHUP, 0, "rovlink fleet stopped"),
        (signal.SIGINT, 130, "rovlink fleet: interrupted"),
    ],
    ids=lambda value: value.name if isinstance(value, signal.Signals) else None,
)
def test_the_live_table_stops_as_a_service_does(
    broker: Mosquitto, how: signal.Signals, status: int, last_line: str
) -> None:
    # Before, SIGTERM (systemctl stop, kill) ended the live table with status 130,
    # "interrupted", where the serving commands (the bridges it watches among them) end with 0.
    from tests.terminals import Terminal

    terminal = Terminal("fleet", "--broker", broker.url)
    try:
        assert terminal.wait_shown(b"no robot has published yet")
        terminal.process.send_signal(how)
        assert terminal.process.wait(timeout=15) == status
        assert terminal.process.stderr is not None
        assert terminal.process.stderr.read().decode().splitlines()[-1] == last_line
    finally:
        terminal.close()


def test_fleet_help_gives_the_range_snapshot_is_checked_against(run_cli: RunCli) -> None:
    # Before, --help did not say it: a user learnt 0.1–60 from a refused value.
    refused = run_cli("fleet", "--broker", "mqtt://127.0.0.1:1", "--snapshot", "61")
    assert refused.status == 2
    assert "60" in refused.err
    text = " ".join(run_cli("fleet", "--help").out.split())
    described = text[text.index("--snapshot SECONDS", text.index("options:")) :]
    assert "0.1–60" in described[: described.index("(default")]


@pytest.mark.integration
async def test_a_retained_online_state_long_unrefreshed_is_silent_not_online(broker: Mosquitto):
    # A broker that lost power restores the states it persisted last: "online" for a robot whose
    # bridge went with it, and no last will ever follows. Before, the snapshot (and the live
    # table, for its first 10 s) showed such a robot online, its link "ok", from a state an
    # hour old; a bridge refreshes its state every 2 s, so its "at" says it is gone.
    now_s = time.time()
    retained = {
        "rovlink/stale/state": f'{{"online": true, "at": {now_s - 3600}, "lock": "locked"}}',
        "rovlink/fresh/state": f'{{"online": true, "at": {now_s}, "lock": "locked"}}',
    }
    lines = await _snapshot_after_retaining(broker, retained)
    stale = next(line for line in lines if " stale " in line)
    assert "silent" in stale
    assert " online " not in stale
    fresh = next(line for line in lines if " fresh " in line)
    assert " online " in fresh


def test_a_retained_state_counts_from_its_at_and_a_live_one_from_now():
    view = FleetView()
    old = b'{"online": true, "at": 1000.0}'
    view.apply("rovlink/a/state", old, 50.0, retained_wall_now_s=1000.0 + SILENT_AFTER_S + 5)
    (row,) = view.rows()
    assert row.presence(50.0) == "silent"
    view.apply("rovlink/a/state", old, 51.0)  # published now (its clock may be wrong)
    assert row.presence(51.0) == "online"
    # Handed over again (the table reconnected to its broker): heard live since all the same.
    view.apply("rovlink/a/state", old, 52.0, retained_wall_now_s=1000.0 + SILENT_AFTER_S + 7)
    assert row.presence(52.0) == "online"
    # A bridge clock ahead of this one's is no reason to call it silent later.
    view.apply("rovlink/b/state", b'{"online": true, "at": 2000.0}', 60.0, retained_wall_now_s=1.0)
    assert view.rows()[1].presence(60.0 + SILENT_AFTER_S - 1) == "online"


def test_a_leak_never_heard_of_is_not_shown_dry():
    # An offline state (the last will) says nothing of the leak, nor does a state that is not a
    # bridge's: the table showed "dry" for them, a robot whose bridge died of the water in it
    # among them. What was heard last stands; what was never heard is "—".
    from rich.console import Console

    from rovlink.cli.fleet import fleet_table

    view = FleetView()
    view.apply("rovlink/gone/state", b'{"online": false, "reason": "bridge connection lost"}', 0.0)
    view.apply("rovlink/wet/telemetry", b'{"depth_cm": 120, "leak": true}', 0.0)
    view.apply("rovlink/wet/state", b'{"online": false, "reason": "bridge connection lost"}', 0.1)
    view.apply("rovlink/dry/state", b'{"online": true, "leak": false}', 0.0)
    console = Console(width=160, record=True)
    console.print(fleet_table(view, now_s=1.0))
    lines = console.export_text().splitlines()
    cells = {
        name: [
            cell.strip() for cell in next(line for line in lines if f" {name} " in line).split("│")
        ]
        for name in ("gone", "wet", "dry")
    }
    leak_column = 4  # (after the border, robot, presence and depth)
    assert cells["gone"][leak_column] == "—"
    assert cells["wet"][leak_column] == "LEAK"
    assert cells["dry"][leak_column] == "dry"


def _many_robots_and_a_leak_last() -> FleetView:
    view = FleetView()
    for number in range(1, 31):
        view.apply(f"rovlink/r{number:02}/state", b'{"online": true, "lock": "locked"}', 0.0)
    view.apply("rovlink/zz-leak/state", b'{"online": true, "leak": true}', 0.0)
    view.apply("rovlink/zz-gone/state", b'{"online": false, "reason": "bridge stopped"}', 0.0)
    return view


@pytest.mark.parametrize("rows", [12, 24])
def test_robots_a_short_terminal_cannot_show_are_said_a_leak_by_name(rows: int) -> None:
    from rich.console import Console

    from rovlink.cli.fleet import fleet_table

    console = Console(width=100, height=rows, record=True)
    console.print(fleet_table(_many_robots_and_a_leak_last(), now_s=1.0, width=100, height=rows))
    lines = console.export_text().splitlines()
    assert len(lines) <= rows
    assert " r01 " in lines[4]  # (after the title and the header) in order, from the first
    shown = sum(1 for line in lines if line.startswith("│ "))
    caption = " ".join(" ".join(lines[4 + shown :]).split())
    assert f"{32 - shown} more robots not shown" in caption
    assert "LEAK: zz-leak" in caption
    assert "1 offline" in caption
    everything = Console(width=100, record=True)
    everything.print(fleet_table(_many_robots_and_a_leak_last(), now_s=1.0, width=100))
    assert "zz-leak" in everything.export_text()  # (no height: a snapshot shows every robot)


@pytest.mark.integration
def test_the_live_table_on_a_short_terminal_names_the_leak_it_cannot_show(
    broker: Mosquitto,
) -> None:
    # Before, the rows past the terminal's height were cut to "...": a robot whose id sorts
    # last, leaking, was not shown, nor said, however long one watched.
    from paho.mqtt import publish

    from tests.terminals import Terminal

    states = {f"rovlink/r{number:02}/state": '{"online": true}' for number in range(1, 31)}
    states["rovlink/zz-leak/state"] = '{"online": true, "leak": true}'
    publish.multiple(
        [
            {"topic": topic, "payload": state, "qos": 1, "retain": True}
            for topic, state in states.items()
        ],
        port=broker.port,
    )
    terminal = Terminal("fleet", "--broker", broker.url, size=(100, 24))
    try:
        # (the caption: "14 more robots not shown …: LEAK: zz-leak", LEAK in red, wrapped)
        assert terminal.wait_until(
            lambda shown: b"more robots not shown" in shown and b"zz-leak" in shown
        ), terminal.shown.decode(errors="replace")
        assert b" r01 " in terminal.shown
    finally:
        terminal.close()
