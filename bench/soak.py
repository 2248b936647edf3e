"""Long runs: what a process holds (descriptors, threads, memory) after many link drops or
connections, read from ``/proc`` (Linux) at the start and after every block of cycles.

    python bench/soak.py client [--aio] [--cycles 300]
    python bench/soak.py server [--controller] [--connections 2000]
    python bench/soak.py pages [--connections 2000]

``client``: a blocking (or asyncio) client with ``reconnect=True`` on ``rovlink sim --tcp``,
the simulator killed (SIGKILL) and started again on the same port each cycle, the robot
unlocked and moving before every other drop; measured in this process. ``server``: clients
that connect to ``rovlink sim --tcp`` (or ``rovlink controller --board sim --tcp``) and leave
in four ways in turn (a query answered, then closed; ``#start!#th.90.40!`` then reset; nothing
sent; half a frame sent); measured in the server's process. ``pages``: WebSocket pages that
connect to ``rovlink web`` and leave in four ways in turn (closed; taking control, then
closed; aborted; a bare handshake, then the TCP connection aborted); measured in the
station's process. Each prints a row per block: descriptors, threads, RSS and CPU time.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable

import rovlink
import rovlink.aio
from rovlink.client import ClientEvent

_ROVLINK = [sys.executable, "-m", "rovlink"]
_TIMEOUT_S = 20.0


def held(pid: int | str = "self") -> str:
    """Descriptors, threads, RSS and CPU time of process ``pid``, from ``/proc``."""
    fds = len(os.listdir(f"/proc/{pid}/fd"))
    threads = len(os.listdir(f"/proc/{pid}/task"))
    with open(f"/proc/{pid}/status", encoding="ascii") as status:
        rss_kb = next(int(line.split()[1]) for line in status if line.startswith("VmRSS"))
    with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
        fields = stat.read().rsplit(")", 1)[1].split()
    cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return f"fds {fds:3d}  threads {threads:2d}  RSS {rss_kb / 1024:6.1f} MB  CPU {cpu_s:6.2f} s"


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def serve(*args: str) -> subprocess.Popen[str]:
    """A rovlink server command, once its ready line is printed (kept in :data:`READY`)."""
    process = subprocess.Popen(
        [*_ROVLINK, *args], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )
    assert process.stdout is not None
    line = process.stdout.readline()
    if "ready" not in line:
        raise SystemExit(f"{args[0]} did not start: {line!r}")
    READY[process.pid] = line
    return process


#: Each server's ready line, by its process id.
READY: dict[int, str] = {}


def link_states() -> tuple[list[str], Callable[[ClientEvent], None]]:
    states: list[str] = []

    def on_event(event: ClientEvent) -> None:
        state = getattr(event, "state", None)
        if state is not None:
            states.append(state)

    return states, on_event


def counted(states: list[str], state: str, count: int) -> Callable[[], bool]:
    return lambda: states.count(state) >= count


def wait_for(done: Callable[[], bool]) -> None:
    deadline_s = time.monotonic() + _TIMEOUT_S
    while not done():
        if time.monotonic() > deadline_s:
            raise SystemExit("timed out")
        time.sleep(0.01)


def soak_client(cycles: int) -> None:
    port = free_port()
    sim = serve("sim", "--tcp", str(port), "--seed", "1")
    states, on_event = link_states()
    rov = rovlink.connect(f"socket://127.0.0.1:{port}", reconnect=True, on_event=on_event)
    rov.depth_cm()
    print(f"{0:6d}  {held()}")
    for cycle in range(1, cycles + 1):
        if cycle % 2:
            rov.start()
            rov.move(90, 30)
        sim.kill()
        sim.wait()
        wait_for(counted(states, "lost", cycle))
        sim = serve("sim", "--tcp", str(port), "--seed", "1")
        wait_for(counted(states, "reconnected", cycle))
        rov.depth_cm()
        if cycle % 50 == 0:
            print(f"{cycle:6d}  {held()}")
    rov.close()
    sim.kill()


async def soak_async_client(cycles: int) -> None:
    loop = asyncio.get_running_loop()
    port = free_port()
    command = ("sim", "--tcp", str(port), "--seed", "1")
    sim = await loop.run_in_executor(None, serve, *command)
    states, on_event = link_states()
    rov = await rovlink.aio.connect(f"socket://127.0.0.1:{port}", reconnect=True, on_event=on_event)
    await rov.depth_cm()
    print(f"{0:6d}  {held()}  tasks {len(asyncio.all_tasks())}")
    for cycle in range(1, cycles + 1):
        if cycle % 2:
            await rov.start()
            await rov.move(90, 30)
        sim.kill()
        sim.wait()
        while states.count("lost") < cycle:
            await asyncio.sleep(0.01)
        sim = await loop.run_in_executor(None, serve, *command)
        await asyncio.wait_for(_reconnected(states, cycle), _TIMEOUT_S)
        await rov.depth_cm()
        if cycle % 50 == 0:
            print(f"{cycle:6d}  {held()}  tasks {len(asyncio.all_tasks())}")
    await rov.close()
    sim.kill()


async def _reconnected(states: list[str], count: int) -> None:
    while states.count("reconnected") < count:
        await asyncio.sleep(0.01)


def soak_server(connections: int, controller: bool) -> None:
    port = free_port()
    if controller:
        server = serve("controller", "--board", "sim", "--tcp", str(port))
    else:
        server = serve("sim", "--tcp", str(port), "--seed", "1")
    print(f"{0:6d}  {held(server.pid)}")
    for number in range(1, connections + 1):
        with socket.create_connection(("127.0.0.1", port), _TIMEOUT_S) as client:
            way = number % 4
            if way == 0:  # a query answered, then closed
                client.sendall(b"#qd!")
                reply = b""
                while b"!" not in reply and (chunk := client.recv(100)):
                    reply += chunk
            elif way == 1:  # moving, then reset
                client.sendall(b"#start!#th.90.40!")
                client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            elif way == 3:  # half a frame
                client.sendall(b"#th.90.")
        if number % 500 == 0:
            print(f"{number:6d}  {held(server.pid)}")
    server.terminate()
    server.wait()


async def soak_pages(connections: int) -> None:
    import websockets  # (the web extra)

    station = serve("web", "sim://", "--port", "0")
    port = int(re.findall(r":(\d+)/", READY[station.pid])[0])
    origin = websockets.Origin(f"http://127.0.0.1:{port}")
    print(f"{0:6d}  {held(station.pid)}")
    for number in range(1, connections + 1):
        way = number % 4
        if way == 3:  # a bare handshake, then the connection aborted
            reader, writer = await asyncio.open_connection("127.0.0.1", port)
            writer.write(
                f"GET /ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n"
                "Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n"
                f"Sec-WebSocket-Version: 13\r\nOrigin: {origin}\r\n\r\n".encode()
            )
            await writer.drain()
            await reader.read(200)
            writer.transport.abort()
        else:
            page = await websockets.connect(f"ws://127.0.0.1:{port}/ws", origin=origin)
            await page.recv()  # its hello
            if way == 1:
                await page.send(json.dumps({"type": "take_control"}))
            if way == 2:
                page.transport.abort()
            else:
                await page.close()
        if number % 500 == 0:
            await asyncio.sleep(0.5)  # (the last pages' ends handled)
            print(f"{number:6d}  {held(station.pid)}")
    station.terminate()
    station.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    runs = parser.add_subparsers(dest="run", required=True)
    client = runs.add_parser("client", help="a client with reconnect=True, the simulator killed")
    client.add_argument("--aio", action="store_true", help="the asyncio client")
    client.add_argument("--cycles", type=int, default=300)
    server = runs.add_parser("server", help="clients connecting to rovlink sim or controller")
    server.add_argument("--controller", action="store_true", help="rovlink controller --board sim")
    server.add_argument("--connections", type=int, default=2000)
    pages = runs.add_parser("pages", help="WebSocket pages connecting to rovlink web")
    pages.add_argument("--connections", type=int, default=2000)
    args = parser.parse_args()
    print(f"{'cycles' if args.run == 'client' else 'conns':>6s}  held")
    if args.run == "client" and args.aio:
        asyncio.run(soak_async_client(args.cycles))
    elif args.run == "client":
        soak_client(args.cycles)
    elif args.run == "server":
        soak_server(args.connections, args.controller)
    else:
        asyncio.run(soak_pages(args.connections))


if __name__ == "__main__":
    main()
