"""A live table of every robot on an MQTT broker: online, depth, leak, lock, link health.

It listens to what ``rovlink mqtt`` bridges publish (rovlink/+/state, telemetry, events); the
retained states show robots that are offline too. Read-only: it sends no command.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, TextIO

from rovlink.cli import link_options
from rovlink.cli.failure import CommandError, NoTerminalError, reason
from rovlink.cli.mqtt import add_broker_options, broker_settings

if TYPE_CHECKING:
    from rich.table import Table
    from rich.text import Text

    from rovlink.bridges.mqtt.broker import BrokerSettings
    from rovlink.bridges.mqtt.fleet_view import FleetView

__all__ = ["EPILOG", "fleet_table"]

EPILOG = """\
examples:
  rovlink fleet --broker mqtt://localhost
  rovlink fleet --broker mqtts://fleet.example --username ops --cafile fleet-ca.pem
  rovlink fleet --broker mqtt://localhost --snapshot 2      print once after 2 s, then exit"""

_TOPICS = ("rovlink/+/state", "rovlink/+/telemetry", "rovlink/+/events")
_REFRESH_HZ = 4
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
        help="listen this long, print the table once and exit (default: a live table)",
    )


def fleet_table(view: FleetView, now_s: float) -> Table:
    """The table of robots as the view has them now.

    Every cell is a :class:`~rich.text.Text`: what came from the broker (any program may publish
    under ``rovlink/``) is shown as it is, never read as markup or obeyed as terminal codes.
    """
    from rich.table import Table  # noqa: PLC0415

    table = Table(title="rovlink fleet", expand=False)
    for column in ("robot", "presence", "depth", "leak", "lock", "mode", "link", "last event"):
        table.add_column(column)
    for row in view.rows():
        presence = row.presence(now_s)
        if presence == "offline" and row.offline_reason:
            note = row.offline_reason
        elif presence == "malformed":
            note = f"state not understood: {row.state_problem}"
        else:
            note = row.last_event or ""
        table.add_row(
            _cell(row.robot),
            _cell(presence, _PRESENCE_STYLES.get(presence, "")),
            _cell("—" if row.depth_cm is None else f"{row.depth_cm} cm"),
            _cell("LEAK", "bold red") if row.leak else _cell("dry"),
            _cell(row.lock or "—"),
            _cell(row.mode or "—"),
            _cell(row.link or "—"),
            _cell(note),
        )
    if not view.rows():
        table.caption = "no robot has published yet"
    return table


def _cell(text: str, style: str = "") -> Text:
    """``text`` as it is: not markup, and its control characters shown, not obeyed."""
    from rich.text import Text  # noqa: PLC0415

    from rovlink.protocol.visible import visible  # noqa: PLC0415

    # A lone surrogate (JSON's "\ud800") can be written in no encoding: shown as its escape.
    printable = text.encode("utf-8", errors="backslashreplace").decode("utf-8")
    return Text(visible(printable), style=style)


def run(args: argparse.Namespace) -> int:
    """Show the table until Ctrl-C (or once, with ``--snapshot``)."""
    broker = broker_settings(args)
    if args.snapshot_s is None and not _is_terminal(sys.stdout):
        # Rich draws a live table on a terminal alone: elsewhere nothing would be written until
        # the command was stopped (`rovlink fleet | head` would wait for ever).
        raise NoTerminalError(
            "the live table needs a terminal, but standard output is not one; "
            "--snapshot SECONDS prints the table once"
        )
    try:
        import aiomqtt  # noqa: F401, PLC0415 - the mqtt extra
    except ImportError:
        raise CommandError("needs aiomqtt: pip install 'rovlink[mqtt]'") from None
    from rovlink.cli.async_run import run_async  # noqa: PLC0415 - not on the path of --help

    run_async(_watch(broker, args.snapshot_s))
    return 0


def _is_terminal(stream: TextIO | None) -> bool:
    try:
        return stream is not None and stream.isatty()
    except (ValueError, OSError):  # closed
        return False


async def _watch(broker: BrokerSettings, snapshot_s: float | None) -> None:
    import asyncio  # noqa: PLC0415

    import aiomqtt  # noqa: PLC0415
    from rich.live import Live  # noqa: PLC0415

    from rovlink.bridges.mqtt.fleet_view import FleetView  # noqa: PLC0415
    from rovlink.cli.rich_console import TableConsole  # noqa: PLC0415

    view = FleetView()
    console = TableConsole()
    tls_params = (
        aiomqtt.TLSParameters(
            ca_certs=None if broker.ca_file is None else str(broker.ca_file),
            certfile=None if broker.cert_file is None else str(broker.cert_file),
            keyfile=None if broker.key_file is None else str(broker.key_file),
        )
        if broker.tls
        else None
    )
    connected = False
    try:
        async with aiomqtt.Client(
            broker.host,
            broker.port,
            username=broker.username,
            password=broker.password,
            tls_params=tls_params,
            tls_insecure=broker.insecure if broker.tls else None,
            timeout=5.0,
        ) as mqtt:
            connected = True
            for topic in _TOPICS:
                await mqtt.subscribe(topic, qos=1)

            async def collect() -> None:
                async for message in mqtt.messages:
                    payload = message.payload if isinstance(message.payload, bytes) else b""
                    view.apply(message.topic.value, payload, time.monotonic())

            collector = asyncio.ensure_future(collect())
            try:
                if snapshot_s is not None:
                    await asyncio.wait([collector], timeout=snapshot_s)
                    if collector.done():  # (the broker went away, or a fault: said, not hidden)
                        collector.result()
                    console.print(fleet_table(view, time.monotonic()))
                    return
                with Live(console=console, refresh_per_second=_REFRESH_HZ) as live:
                    while not collector.done():
                        live.update(fleet_table(view, time.monotonic()))
                        await asyncio.sleep(1 / _REFRESH_HZ)
                collector.result()
            finally:
                collector.cancel()
                await asyncio.gather(collector, return_exceptions=True)
    except aiomqtt.MqttError as error:
        where = "broker" if connected else "cannot connect to the broker"
        raise CommandError(f"{where} {broker.describe()}: {reason(error)}") from None
