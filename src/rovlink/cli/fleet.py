"""A live table of every robot on an MQTT broker: online, depth, leak, lock, link health.

It listens to what ``rovlink mqtt`` bridges publish (rovlink/+/state, telemetry, events); the
retained states show robots that are offline too. Read-only: it sends no command.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

from rovlink.cli import link_options
from rovlink.cli.extras import needs_extra
from rovlink.cli.failure import CommandError, NoTerminalError, is_terminal
from rovlink.cli.mqtt import add_broker_options, broker_settings

if TYPE_CHECKING:
    import aiomqtt
    from rich.table import Table
    from rich.text import Text

    from rovlink.bridges.mqtt.broker import BrokerSettings
    from rovlink.bridges.mqtt.fleet_view import FleetView, RobotRow
    from rovlink.cli.rich_console import TableConsole

__all__ = ["EPILOG", "fleet_table"]

EPILOG = """\
examples:
  rovlink fleet --broker mqtt://localhost
  rovlink fleet --broker mqtts://fleet.example --username ops --cafile fleet-ca.pem
  rovlink fleet --broker mqtt://localhost --snapshot 2      print once after 2 s, then exit"""

_TOPICS = ("rovlink/+/state", "rovlink/+/telemetry", "rovlink/+/events")
_REFRESH_HZ = 4
#: Waits before reconnecting to a broker that was lost, doubling up to the most, s.
_FIRST_RETRY_S = 0.5
_MOST_RETRY_S = 8.0
#: How long the broker has to answer a request (connecting, subscribing), s.
_REPLY_TIMEOUT_S = 5.0
_PRESENCE_STYLES = {"online": "green", "silent": "yellow", "offline": "red", "malformed": "magenta"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``fleet``'s options."""
    add_broker_options(parser)
    parser.add_argument(
        "--snapshot",
        dest="snapshot_s",
        type=lambda text: link_options.bounded_float(text, 0.1, 60.0, " s"),
        default=None,
        metavar="SECONDS",
        help="listen this long, 0.1–60, print the table once and exit (default: a live table)",
    )


#: The columns, in order; robot and presence are always shown.
_COLUMNS = ("robot", "presence", "depth", "leak", "lock", "mode", "link", "last event")
#: The columns that give way, first to last, when the terminal is too narrow for them all.
_GIVE_WAY = ("last event", "mode", "link", "lock", "depth", "leak")


def fleet_table(
    view: FleetView,
    now_s: float,
    width: int | None = None,
    height: int | None = None,
    note: str | None = None,
) -> Table:
    """The table of robots as the view has them now, in ``width`` columns and ``height`` rows
    if given, with ``note`` first in its caption (a broker lost).

    Every cell is a :class:`~rich.text.Text`: what came from the broker (any program may publish
    under ``rovlink/``) is shown as it is, never read as markup or obeyed as terminal codes.
    Where ``width`` is too narrow for every column, the least needed give way (the caption
    names them) rather than every column shrinking to a letter and an ellipsis. Where
    ``height`` is too short for every robot, the last ones by id give way, and the caption says
    how many, naming those that leak and counting those offline or silent: a live table cut
    at the terminal's bottom showed them as "...".
    """
    robots = view.rows()
    rows = [_row_cells(row, now_s) for row in robots]
    shown = list(_COLUMNS)
    table = _table(shown, rows)
    column_caption: str | None = None
    if width is not None:
        hidden: list[str] = []
        for column in _GIVE_WAY:
            if _minimum_width(table) <= width:
                break
            shown.remove(column)
            hidden.append(column)
            table = _table(shown, rows)
        if hidden:
            hidden.sort(key=_COLUMNS.index)
            column_caption = f"not shown: {', '.join(hidden)} (widen the terminal)"
    if not rows:
        column_caption = "no robot has published yet"
    captions = [text for text in (note, column_caption) if text is not None]
    table.caption = "; ".join(captions) or None
    if rows and width is not None and height is not None:
        kept = len(rows)
        while kept > 0 and (overflow := _lines(table, width) - height) > 0:
            kept = max(0, kept - overflow)  # (a row takes a line at least: a few rounds)
            table = _table(shown, rows[:kept])
            table.caption = _caption_of_the_hidden(robots[kept:], now_s, captions)
    return table


def _lines(table: Table, width: int) -> int:
    """How many lines ``table`` takes on a terminal ``width`` columns wide."""
    import io  # noqa: PLC0415

    from rich.console import Console  # noqa: PLC0415

    console = Console(file=io.StringIO(), width=width)
    return len(console.render_lines(table, console.options, pad=False))


def _caption_of_the_hidden(hidden: list[RobotRow], now_s: float, before: list[str]) -> Text:
    """``12 more robots not shown …: LEAK: rov-9; 2 offline`` after the captions ``before``
    (robot ids as text, not markup)."""
    from rich.text import Text  # noqa: PLC0415

    what = "1 more robot" if len(hidden) == 1 else f"{len(hidden)} more robots"
    caption = Text("".join(f"{text}; " for text in before))
    caption.append(f"{what} not shown (a taller terminal shows them)")
    leaking = [row.robot for row in hidden if row.leak]
    if leaking:
        caption.append(": ")
        caption.append("LEAK", "bold red")
        caption.append_text(_cell(": " + ", ".join(leaking)))
    presences = [row.presence(now_s) for row in hidden]
    for presence in ("offline", "silent", "malformed"):
        count = presences.count(presence)
        if count:
            caption.append(f"; {count} {presence}")
    return caption


def _row_cells(row: RobotRow, now_s: float) -> dict[str, Text]:
    """One robot's cells, by column."""
    presence = row.presence(now_s)
    if presence == "offline" and row.offline_reason:
        note = row.offline_reason
    elif presence == "malformed":
        note = f"state not understood: {row.state_problem}"
    else:
        note = row.last_event or ""
    return {
        "robot": _cell(f"{row.robot} (simulated)" if row.simulated else row.robot),
        "presence": _cell(presence, _PRESENCE_STYLES.get(presence, "")),
        "depth": _cell("—" if row.depth_cm is None else f"{row.depth_cm} cm"),
        "leak": _leak_cell(row.leak),
        "lock": _cell(row.lock or "—"),
        "mode": _cell(row.mode or "—"),
        "link": _cell(row.link or "—"),
        "last event": _cell(note),
    }


def _leak_cell(leak: bool | None) -> Text:
    if leak is None:  # (never heard: an offline state does not say)
        return _cell("—")
    return _cell("LEAK", "bold red") if leak else _cell("dry")


def _table(columns: list[str], rows: list[dict[str, Text]]) -> Table:
    from rich.table import Table  # noqa: PLC0415

    table = Table(title="rovlink fleet", expand=False)
    for column in columns:
        table.add_column(column)
    for cells in rows:
        table.add_row(*(cells[column] for column in columns))
    return table


def _minimum_width(table: Table) -> int:
    """The fewest columns ``table`` takes with no cell cut short (its words wrapped)."""
    import io  # noqa: PLC0415

    from rich.console import Console  # noqa: PLC0415
    from rich.measure import Measurement  # noqa: PLC0415

    console = Console(file=io.StringIO(), width=10_000)
    return Measurement.get(console, console.options, table).minimum


def _cell(text: str, style: str = "") -> Text:
    """``text`` as it is: not markup, and its control characters shown, not obeyed."""
    from rich.text import Text  # noqa: PLC0415

    from rovlink.protocol.visible import visible  # noqa: PLC0415

    # A lone surrogate (JSON's "\ud800") can be written in no encoding: shown as its escape.
    printable = text.encode("utf-8", errors="backslashreplace").decode("utf-8")
    return Text(visible(printable), style=style)


def run(args: argparse.Namespace) -> int:
    """Show the table until Ctrl-C, SIGTERM or SIGHUP (or once, with ``--snapshot``)."""
    broker = broker_settings(args)
    if args.snapshot_s is None and not is_terminal(sys.stdout):
        # Rich draws a live table on a terminal alone: elsewhere nothing would be written until
        # the command was stopped (`rovlink fleet | head` would wait for ever).
        raise NoTerminalError(
            "the live table needs a terminal, but standard output is not one; "
            "--snapshot SECONDS prints the table once"
        )
    with needs_extra("mqtt"):
        import aiomqtt  # noqa: F401, PLC0415 - the mqtt extra
    from rovlink.cli.async_run import run_async, serve_async  # noqa: PLC0415 - not on --help

    if args.snapshot_s is not None:
        run_async(_watch(broker, args.snapshot_s))  # (ended by a signal: interrupted, 130)
    else:
        # The live table runs until stopped, as a service: SIGTERM and SIGHUP end it cleanly
        # (status 0); Ctrl-C says interrupted (130), as for every command.
        serve_async(_watch(broker, None), "rovlink fleet")
    return 0


async def _watch(broker: BrokerSettings, snapshot_s: float | None) -> None:
    import aiomqtt  # noqa: PLC0415

    from rovlink.bridges.mqtt.fleet_view import FleetView  # noqa: PLC0415
    from rovlink.cli.rich_console import TableConsole  # noqa: PLC0415

    view = FleetView()
    console = TableConsole()
    connected = False
    try:
        if snapshot_s is not None:
            async with _client(broker) as mqtt:
                connected = True
                await _snapshot(mqtt, view, console, snapshot_s)
            return
        await _live(broker, view, console)
    except aiomqtt.MqttError as error:
        # In the bridge's words (aiomqtt's are "[code:135] Not authorized", or for a
        # certificate not trusted "Operation not permitted").
        from rovlink.bridges.mqtt.broker_failure import broker_failure  # noqa: PLC0415

        failure = broker_failure(
            error, broker, connected=connected, reply_timeout_s=_REPLY_TIMEOUT_S
        )
        raise CommandError(f"broker {broker.describe()}: {failure}") from None


def _client(broker: BrokerSettings) -> aiomqtt.Client:
    """A client of the broker, not yet connected (``async with`` connects it)."""
    import aiomqtt  # noqa: PLC0415

    from rovlink.bridges.mqtt.broker import KEEPALIVE_S  # noqa: PLC0415

    tls_params = (
        aiomqtt.TLSParameters(
            ca_certs=None if broker.ca_file is None else str(broker.ca_file),
            certfile=None if broker.cert_file is None else str(broker.cert_file),
            keyfile=None if broker.key_file is None else str(broker.key_file),
        )
        if broker.tls
        else None
    )
    return aiomqtt.Client(
        broker.host,
        broker.port,
        username=broker.username,
        password=broker.password,
        tls_params=tls_params,
        tls_insecure=broker.insecure if broker.tls else None,
        timeout=_REPLY_TIMEOUT_S,
        keepalive=KEEPALIVE_S,  # (a broker gone silent is said, as the bridges notice it)
    )


async def _collect(mqtt: aiomqtt.Client, view: FleetView) -> None:
    """Subscribe, and feed the view every message until the connection ends (MqttError)."""
    for topic in _TOPICS:
        await mqtt.subscribe(topic, qos=1)
    async for message in mqtt.messages:
        payload = message.payload if isinstance(message.payload, bytes) else b""
        # A retained state may be hours old (a broker restored from its persistence): its
        # "at" says when it was heard, not its arrival.
        retained_wall_now_s = time.time() if message.retain else None
        view.apply(
            message.topic.value,
            payload,
            time.monotonic(),
            retained_wall_now_s=retained_wall_now_s,
        )


async def _snapshot(
    mqtt: aiomqtt.Client, view: FleetView, console: TableConsole, snapshot_s: float
) -> None:
    import asyncio  # noqa: PLC0415

    collector = asyncio.ensure_future(_collect(mqtt, view))
    try:
        await asyncio.wait([collector], timeout=snapshot_s)
        if collector.done():  # (the broker went away, or a fault: said, not hidden)
            collector.result()
        console.print(fleet_table(view, time.monotonic(), console.width))
    finally:
        collector.cancel()
        await asyncio.gather(collector, return_exceptions=True)


async def _live(broker: BrokerSettings, view: FleetView, console: TableConsole) -> None:
    """The live table until Ctrl-C. A broker that cannot be reached at first is an error
    (MqttError); one lost later is reconnected to, with backoff, as the bridges do, and the
    caption says so meanwhile (the rows are as they were last heard)."""
    import asyncio  # noqa: PLC0415

    import aiomqtt  # noqa: PLC0415
    from rich.live import Live  # noqa: PLC0415

    from rovlink.bridges.mqtt.broker_failure import broker_failure  # noqa: PLC0415

    trouble: str | None = None

    def draw() -> Table:
        return fleet_table(view, time.monotonic(), console.width, console.height, trouble)

    async def show_until(live: Live, done: Callable[[], bool]) -> None:
        while not done():
            live.update(draw())
            await asyncio.sleep(1 / _REFRESH_HZ)

    live: Live | None = None
    retry_s = _FIRST_RETRY_S
    with contextlib.ExitStack() as screen:
        while True:
            connected = False
            try:
                async with _client(broker) as mqtt:
                    connected = True
                    if live is None:  # (the table shows once the broker is reached)
                        live = screen.enter_context(
                            Live(console=console, refresh_per_second=_REFRESH_HZ)
                        )
                    trouble, retry_s = None, _FIRST_RETRY_S
                    collector = asyncio.ensure_future(_collect(mqtt, view))
                    try:
                        await show_until(live, collector.done)
                        collector.result()
                    finally:
                        collector.cancel()
                        await asyncio.gather(collector, return_exceptions=True)
            except aiomqtt.MqttError as error:
                if live is None:
                    raise
                failure = broker_failure(
                    error, broker, connected=connected, reply_timeout_s=_REPLY_TIMEOUT_S
                )
                trouble = f"broker {broker.describe()}: {failure}; reconnecting in {retry_s:g} s"
            assert live is not None
            retry_at = time.monotonic() + retry_s

            def waited(at: float = retry_at) -> bool:
                return time.monotonic() >= at

            await show_until(live, waited)
            retry_s = min(2 * retry_s, _MOST_RETRY_S)
