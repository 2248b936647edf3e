"""A noisy tether: queries and commands through ``fault://`` at a bit error rate, with and without
checksums, against the simulated controller.

The host sends a varied stream of set commands (``mvpdp``, ``mvpdi``, ``mvpidd``, ``mgmp``, ``th``
with random values, so that a damaged one differs from every one sent), each followed by a query
of one reply (``qd``, ``qr``, ``q.l``, ``qro``, ``qpi``, ``qhe``) and now and then a ``qsa``,
through a fault-injecting link. The simulated controller's dispatch is watched: every
command it acts on that the host never sent is a corrupted command executed. The same seeds run
with checksums on (CRC-8) and off, in the same run, so the difference is the checksum's.

    PYTHONPATH=src python bench/faults.py [--ber 1e-3] [--rounds 2000] [--seeds 3]
"""

from __future__ import annotations

import argparse
import collections
import random
import statistics
import time
from dataclasses import dataclass, field

from rovlink.client import Client, ClientOptions, QueryTimeoutError
from rovlink.client.events import ReplyReceived
from rovlink.client.links import PortLink
from rovlink.faults import FaultPort, FaultSettings
from rovlink.protocol import Command, Frame
from rovlink.sim.port import open_port

TARGET_ANSWERED = 0.999
#: The queries with one reply each; qsa (six replies, 55 bytes) is counted apart.
SINGLE_QUERIES = ("qd", "qr", "q.l", "qro", "qpi", "qhe")
QSA_SHARE = 0.1


@dataclass
class Run:
    """One run's figures."""

    checksum: bool
    seed: int
    queries: int = 0
    answered: int = 0
    latencies_ms: list[float] = field(default_factory=list)
    qsa_queries: int = 0
    qsa_answered: int = 0
    commands_sent: int = 0
    corrupted_executed: int = 0
    examples: list[str] = field(default_factory=list)
    bits_flipped: int = 0
    replies_accepted: int = 0
    corrupted_replies_accepted: int = 0


def _workload(rng: random.Random) -> Command:
    name = rng.choice(("mvpdp", "mvpdi", "mvpidd", "mgmp", "th"))
    if name == "th":
        return Command("th", (rng.randrange(361), rng.randrange(101)))
    if name == "mgmp":
        return Command("mgmp", (rng.randrange(256),))
    return Command(name, (rng.randrange(100),))


def run_once(ber: float, checksum: bool, seed: int, rounds: int, retries: int) -> Run:
    result = Run(checksum, seed)
    sim = open_port(seed=seed, timeout=0.05)
    executed: list[Command] = []
    controller = sim.controller
    dispatch = controller._frame

    def watched(frame: Frame) -> None:
        if isinstance(frame.message, Command):
            executed.append(frame.message)
        dispatch(frame)

    controller._frame = watched  # type: ignore[method-assign]
    # Every reply value the controller wrote: a reply the host accepts that is not among them
    # was damaged on the way and taken for a good one.
    written: set[tuple[str, tuple[int, ...]]] = set()
    read_sensors = controller._sensor_values

    def recorded(names: tuple[str, ...]) -> dict[str, int]:
        values = read_sensors(names)
        written.update((name, (value,)) for name, value in values.items())
        return values

    controller._sensor_values = recorded  # type: ignore[method-assign]
    accepted: list[tuple[str, tuple[int, ...]]] = []

    def on_event(event: object) -> None:
        if isinstance(event, ReplyReceived):
            accepted.extend((reply.name, reply.values) for reply in event.responses)

    port = FaultPort(PortLink(sim, "sim"), FaultSettings(ber=ber, seed=seed))
    options = ClientOptions(
        timeout_s=0.05,
        retries=retries,
        checksum=checksum,
        keepalive_s=None,
        boot_timeout_s=2.0,
        on_event=on_event,
    )
    rng = random.Random(seed)
    sent: collections.Counter[Command] = collections.Counter()
    client = Client(PortLink(port, "fault"), options)
    try:
        for _ in range(rounds):
            command = _workload(rng)
            sent[command] += 1
            client.send(command)
            result.commands_sent += 1
            query = Command(rng.choice(SINGLE_QUERIES))
            result.queries += 1
            started = time.perf_counter()
            try:
                client.send(query)
                result.answered += 1
                result.latencies_ms.append((time.perf_counter() - started) * 1000.0)
            except QueryTimeoutError:
                pass
            if rng.random() < QSA_SHARE:
                result.qsa_queries += 1
                try:
                    client.send(Command("qsa"))
                    result.qsa_answered += 1
                except QueryTimeoutError:
                    pass
    finally:
        client.close()
    result.bits_flipped = sum(c.bits_flipped for c in port.counters.values())
    result.replies_accepted = len(accepted)
    result.corrupted_replies_accepted = sum(reply not in written for reply in accepted)
    for command in executed:
        # Queries are not counted: a damaged query is answered under its own name (and the host
        # takes no reply of another name for it); the mode frames are the session's own.
        if command in sent or command.spec.is_query or command.spec.exact_match:
            continue
        result.corrupted_executed += 1
        if len(result.examples) < 5:
            result.examples.append(str(command))
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ber", type=float, default=1e-3)
    parser.add_argument("--rounds", type=int, default=2000)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--retries", type=int, default=5)
    args = parser.parse_args()
    print(
        f"BER {args.ber:g}, {args.rounds} commands and {args.rounds} queries per run, "
        f"retries {args.retries}, query timeout 50 ms"
    )
    for checksum in (True, False):
        runs = [
            run_once(args.ber, checksum, seed, args.rounds, args.retries)
            for seed in range(1, args.seeds + 1)
        ]
        queries = sum(r.queries for r in runs)
        answered = sum(r.answered for r in runs)
        latencies = sorted(ms for r in runs for ms in r.latencies_ms)
        p99 = latencies[int(0.99 * (len(latencies) - 1))] if latencies else float("nan")
        corrupted = sum(r.corrupted_executed for r in runs)
        commands = sum(r.commands_sent for r in runs)
        label = "checksums on (crc8)" if checksum else "checksums off"
        share = answered / queries if queries else 0.0
        verdict = "meets" if share >= TARGET_ANSWERED else "misses"
        print(f"\n{label}:")
        print(
            f"  queries answered      {answered}/{queries} = {share:.4%} "
            f"({verdict} the {TARGET_ANSWERED:.1%} target)"
        )
        qsa = sum(r.qsa_queries for r in runs)
        qsa_answered = sum(r.qsa_answered for r in runs)
        print(
            f"  qsa answered          {qsa_answered}/{qsa} = {qsa_answered / max(qsa, 1):.2%} "
            "(six replies, about 55 bytes: one damaged bit fails the whole attempt)"
        )
        print(
            f"  latency               median {statistics.median(latencies):.2f} ms, "
            f"p99 {p99:.2f} ms, max {latencies[-1]:.2f} ms"
        )
        print(
            f"  corrupted commands executed  {corrupted} of {commands} sent "
            f"({corrupted / commands:.3%})"
        )
        replies = sum(r.replies_accepted for r in runs)
        bad_replies = sum(r.corrupted_replies_accepted for r in runs)
        print(
            f"  corrupted replies taken for good  {bad_replies} of {replies} "
            f"({bad_replies / max(replies, 1):.3%})"
        )
        print(f"  bits flipped          {sum(r.bits_flipped for r in runs)}")
        examples = [example for r in runs for example in r.examples][:6]
        if examples:
            print(f"  e.g. executed but never sent: {', '.join(examples)}")


if __name__ == "__main__":
    main()
