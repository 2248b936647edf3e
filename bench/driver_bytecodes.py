"""Where the asyncio client's work per query goes: Python bytecodes per query, by function.

    python bench/driver_bytecodes.py [--queries 1000] [--top 15] [--checksum]

Against ``fast_controller.c`` (see ``bench/driver_cpu.py``), ``#qd!`` → ``$qd.N!`` one query at a
time, three ways in one event loop: raw asyncio streams (``write``, ``readuntil(b"!")``); the
same with one timer kept armed on the loop, as any client with a reply deadline keeps (the raw
loop has none); and ``rovlink.aio.connect(url, keepalive=None).depth_cm()``. Each way is warmed
up past the controller's counter of replies (10,000), so that its replies are frames the decoder
has met, as in the CPU benchmark's long runs. The counts come from ``sys.monitoring``'s
instruction events (Python 3.12 and later); what C code does (the selector's system calls, the
C implementation of futures and tasks) is not counted: ``bench/driver_instructions.py`` counts
every machine instruction, without saying where.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from collections import Counter
from collections.abc import Awaitable, Callable
from types import CodeType

import rovlink.aio
from fast_controller import FastController, NoCompilerError, running_fast_controller
from rovlink.protocol import Command, encode

#: Past the fast controller's counter (its replies go 0 to 9,999, then again).
WARM_UP_QUERIES = 10_300
_TOOL_ID = 3  # one of the ids sys.monitoring leaves to tools such as this one


class BytecodeCounter:
    """Counts the bytecodes executed per code object while :meth:`counting` is on."""

    def __init__(self) -> None:
        self.counts: Counter[CodeType] = Counter()
        monitoring = sys.monitoring  # type: ignore[attr-defined,unused-ignore]
        monitoring.use_tool_id(_TOOL_ID, "rovlink bytecode count")
        monitoring.register_callback(_TOOL_ID, monitoring.events.INSTRUCTION, self._count)

    def _count(self, code: CodeType, offset: int) -> None:
        self.counts[code] += 1

    async def count(
        self, query: Callable[[], Awaitable[object]], queries: int
    ) -> Counter[CodeType]:
        """The bytecodes of ``queries`` awaits of ``query()``, by code object."""
        monitoring = sys.monitoring  # type: ignore[attr-defined,unused-ignore]
        self.counts.clear()
        monitoring.set_events(_TOOL_ID, monitoring.events.INSTRUCTION)
        try:
            for _ in range(queries):
                await query()
        finally:
            monitoring.set_events(_TOOL_ID, 0)
        return Counter(self.counts)


async def _measure(
    controller: FastController, arguments: argparse.Namespace
) -> dict[str, Counter[CodeType]]:
    query = encode(Command("qd"), checksum="crc8" if arguments.checksum else None)
    reader, writer = await asyncio.open_connection(controller.host, controller.port)
    if arguments.checksum:
        writer.write(b"#crcon!")

    async def raw_query() -> bytes:
        writer.write(query)
        return await reader.readuntil(b"!")

    counter = BytecodeCounter()
    results: dict[str, Counter[CodeType]] = {}
    loop = asyncio.get_running_loop()
    try:
        async with rovlink.aio.connect(
            controller.url, keepalive=None, checksum=arguments.checksum
        ) as rov:
            ways: list[tuple[str, Callable[[], Awaitable[object]], bool]] = [
                ("raw asyncio streams", raw_query, False),
                ("raw streams + a timer armed", raw_query, True),
                ("rovlink.aio.connect", rov.depth_cm, False),
            ]
            for name, way_query, with_timer in ways:
                for _ in range(WARM_UP_QUERIES):
                    await way_query()
                # (The client's own timer is gone by now for the raw ways: the warm-up of the
                # raw ways comes first, and the client's timer is not re-armed while idle.)
                timer = loop.call_later(3600.0, lambda: None) if with_timer else None
                try:
                    results[name] = await counter.count(way_query, arguments.queries)
                finally:
                    if timer is not None:
                        timer.cancel()
    finally:
        writer.close()
        await writer.wait_closed()
    return results


def _where(code: CodeType) -> str:
    parts = code.co_filename.replace("\\", "/").split("/")
    name = getattr(code, "co_qualname", code.co_name)  # (3.11 and later)
    return f"{name} ({'/'.join(parts[-2:])}:{code.co_firstlineno})"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--queries", type=int, default=1000, help="queries counted per way")
    parser.add_argument("--top", type=int, default=15, help="functions listed per way")
    parser.add_argument("--checksum", action="store_true", help="CRC-8 checksum mode on")
    arguments = parser.parse_args()
    if sys.version_info < (3, 12):
        print("driver_bytecodes: needs Python 3.12 or later (sys.monitoring)", file=sys.stderr)
        return 2
    try:
        with running_fast_controller() as controller:
            results = asyncio.run(_measure(controller, arguments))
    except NoCompilerError as error:
        print(f"driver_bytecodes: {error}", file=sys.stderr)
        return 2
    print(
        f"{arguments.queries} queries per way, checksums {'on' if arguments.checksum else 'off'}, "
        f"Python {sys.version.split()[0]}"
    )
    for name, counts in results.items():
        total = sum(counts.values()) / arguments.queries
        print(f"\n{name}: {total:,.0f} bytecodes per query")
        for code, count in counts.most_common(arguments.top):
            print(f"  {count / arguments.queries:8.1f}  {_where(code)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
