"""Put a fault-injecting proxy in front of a controller: programs in any language connect to the
TCP port and see the controller through seeded bit errors, losses, duplicates and delays. The
same faults are available to rovlink's own tools as a fault:// URL. One client at a time: a
second one is told it is busy and disconnected. When a client disconnects, and when the proxy
stops, the controller gets #stop!."""

from __future__ import annotations

import argparse
from collections.abc import Callable

from rovlink.cli.failure import CommandError, UsageError, reason
from rovlink.cli.interrupt import ServingSignals, say_last, say_ready
from rovlink.cli.link_options import bounded_float, log_warnings
from rovlink.cli.tcp_endpoint import REMOTE_MARK, listen_address, refuse_remote, tcp_endpoint

__all__ = ["EPILOG"]

EPILOG = """\
examples:
  rovlink fault --listen socket://127.0.0.1:5761 --to /dev/ttyUSB0 --ber 1e-3 --seed 1
  rovlink fault --listen socket://127.0.0.1:5761 --to sim:// --drop 0.01 --delay-ms 5
  rovlink check 'fault://?inner=sim://&ber=1e-4&seed=3'     the same faults as a URL"""


_MAX_PORT = 65535


def _probability(maximum: float) -> Callable[[str], float]:
    return lambda text: bounded_float(text, 0.0, maximum)


def _listen_address(text: str) -> tuple[str, int]:
    """``--listen``'s host and port. Port 0 picks a free one, as ``rovlink sim --tcp 0`` and
    ``rovlink record --tap`` do: the ready line says which (a test or a CI job needs no fixed
    port)."""
    if not text.startswith("socket://"):
        raise UsageError(f"--listen: expected socket://HOST:PORT, got {text!r}")
    host, colon, port = text[len("socket://") :].rstrip("/").rpartition(":")
    if not colon or not host.strip("[]") or not port.isdigit() or int(port) > _MAX_PORT:
        raise UsageError(
            f"--listen: {text!r}: expected socket://HOST:PORT with a port in 0–{_MAX_PORT} "
            "(0: a free one)"
        )
    return host.strip("[]"), int(port)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``fault``'s options."""
    parser.add_argument(
        "--listen",
        required=True,
        metavar="socket://HOST:PORT",
        help="where programs connect (port 0: a free one, named in the ready line)",
    )
    parser.add_argument("--to", required=True, metavar="URL", help="the controller's port or URL")
    parser.add_argument(
        "--ber",
        type=_probability(0.5),
        default=0.0,
        metavar="RATE",
        help="bit error rate, 0–0.5 (default: 0)",
    )
    parser.add_argument(
        "--drop",
        type=_probability(1.0),
        default=0.0,
        metavar="RATE",
        help="byte loss rate, 0–1 (default: 0)",
    )
    parser.add_argument(
        "--dup",
        type=_probability(1.0),
        default=0.0,
        metavar="RATE",
        help="byte duplicate rate, 0–1 (default: 0)",
    )
    parser.add_argument(
        "--delay-ms",
        type=lambda text: bounded_float(text, 0.0, 10_000.0, " ms"),
        default=0.0,
        metavar="MS",
        help="delay of every chunk, ms, 0–10000 (default: 0)",
    )
    parser.add_argument(
        "--jitter-ms",
        type=lambda text: bounded_float(text, 0.0, 10_000.0, " ms"),
        default=0.0,
        metavar="MS",
        help="random extra or less delay, up to this, ms, at most --delay-ms (default: 0)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the faults (default: 0)")
    parser.add_argument(
        "--allow-remote",
        action="store_true",
        help="let --listen use an address other computers reach; the protocol has no "
        "authentication, so anyone who reaches it drives the robot",
    )


def run(args: argparse.Namespace) -> int:
    """Serve until Ctrl-C or SIGTERM; print what the faults did and how many clients came."""
    from rovlink.client.errors import ConnectError  # noqa: PLC0415
    from rovlink.client.links import open_link  # noqa: PLC0415
    from rovlink.client.url import parse_url  # noqa: PLC0415
    from rovlink.faults import FaultPort, FaultSettings  # noqa: PLC0415
    from rovlink.faults.proxy import FaultProxy  # noqa: PLC0415

    # Each URL's error names its option: both are URLs, and either may be the wrong one.
    listen_host, listen_port = _listen_address(args.listen)
    try:
        target = parse_url(args.to)
    except ValueError as error:
        raise UsageError(f"--to: {error}") from None
    log_warnings()  # (a listener other computers reach, a #stop! the lost link could not take)
    if args.jitter_ms > args.delay_ms:
        raise UsageError(
            f"--jitter-ms {args.jitter_ms:g} is more than --delay-ms {args.delay_ms:g}"
        )
    try:
        settings = FaultSettings(
            ber=args.ber,
            drop=args.drop,
            dup=args.dup,
            delay_ms=args.delay_ms,
            jitter_ms=args.jitter_ms,
            seed=args.seed,
        )
    except ValueError as error:
        raise UsageError(str(error)) from None
    # As rovlink controller: whoever reaches the port drives the robot, unauthenticated.
    refuse_remote("--listen", args.listen, listen_host, allow_remote=args.allow_remote)
    try:
        link = open_link(target)
    except ConnectError as error:
        raise CommandError(str(error)) from None
    port = FaultPort(link, settings, name=f"fault proxy to {link.description}")
    signals: ServingSignals | None = None
    try:
        try:
            proxy = FaultProxy(port, listen_host, listen_port)
        except OSError as error:
            where = listen_address(listen_host, listen_port)
            raise CommandError(f"cannot listen on {where}: {reason(error)}") from None
        signals = ServingSignals()
        host, tcp_port = proxy.address
        shown_host = f"[{host}]" if ":" in host else host  # (a URL that opens: IPv6 in [])
        # Said loudly, and warned of, when other computers reach it: as rovlink sim does.
        endpoint = tcp_endpoint(host, tcp_port, "rovlink.faults")
        remote = f" {REMOTE_MARK}" if endpoint.endswith(REMOTE_MARK) else ""
        say_ready(
            f"rovlink fault ready: socket://{shown_host}:{tcp_port}{remote} -> {link.description} "
            f"(ber {settings.ber:g}, drop {settings.drop:g}, dup {settings.dup:g}, "
            f"delay {settings.delay_ms:g}±{settings.jitter_ms:g} ms, seed {settings.seed}); "
            "Ctrl-C stops"
        )
        proxy.serve(signals.stopping.is_set)
    finally:
        port.close()
        if signals is not None:
            signals.restore()
    for direction, counters in port.counters.items():
        say_last(f"{direction.replace('_', ' ')}: {counters.summary()}")
    say_last(f"clients: {proxy.clients_served} served, {proxy.clients_refused} refused (busy)")
    if proxy.lost is not None:
        raise CommandError(f"the controller's link was lost: {proxy.lost}")
    if signals is not None:
        signals.say_stopped("rovlink fault")
        signals.finish()  # (Ctrl-C: status 130; SIGTERM, SIGHUP: a service stopped, 0)
    return 0
