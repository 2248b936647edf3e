"""The web station: gamepad-to-wire latency, and the server's CPU with five browsers watching.

    PYTHONPATH=src python bench/station_latency.py [--changes 1000] [--cpu-seconds 30]

Needs the ``web`` and ``test`` extras and Debian's chromium (``apt-get install chromium``).
A simulated robot is served on TCP in this process and records when each frame reaches its
controller; ``rovlink web`` runs as a subprocess on it, as a pilot runs it.

1. Gamepad to wire. A fake gamepad (``tests/station/fake_gamepad.js``) is injected in a real
   chromium page; with the dead-man held, the stick is moved ``--changes`` times to a new
   direction, each time waiting for ``#th.D.100!`` to reach the controller, and 25 ms more
   (the relay sends non-zero motion at most every 20 ms; the changes are then also made back
   to back, to show that interval). The time runs from just before the page's pad is changed
   (so it includes the page's poll, its WebSocket message, the server's relay and the driver)
   to the frame's arrival. In the same run, one
   after the other, the same changes are sent by a WebSocket client with no browser (the
   server's and driver's share) and by the asyncio driver alone (``move()``, the floor).
   Target: p99 ≤ 50 ms.
2. Telemetry to five browsers at 10 Hz. The station's process CPU time (user + system, from
   /proc) over ``--cpu-seconds`` with five chromium pages open, against the same station with
   no page open, in the same run. Target: under 10 % of one core with five pages. Each page's
   count of telemetry messages is checked against the 10 Hz it should get.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import re
import selectors
import shutil
import statistics
import subprocess
import sys
import threading
import time
from collections.abc import Hashable, Iterator
from contextlib import contextmanager
from pathlib import Path

from playwright.sync_api import sync_playwright
from websockets.sync.client import connect as ws_connect

import rovlink.aio
from rovlink.protocol import Command, Decoder, Frame
from rovlink.sim.server import SimServer

ROOT = Path(__file__).resolve().parents[1]
FAKE_GAMEPAD = (ROOT / "tests" / "station" / "fake_gamepad.js").read_text(encoding="utf-8")
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--headless",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
TARGET_P99_MS = 50.0
TARGET_CPU_PERCENT = 10.0
#: Between one change's frame and the next change: longer than the relay's 20 ms between
#: non-zero motion frames, so that a change's own latency is measured. Back to back, each
#: change also waits out that interval (a stick in constant motion).
SPACING_S = 0.025
_URL = re.compile(r"http://\S+?/(?=[ ;]|$)")


class RecordedRobot:
    """A simulated robot on TCP; ``wait_for(text)`` returns when that frame reached it."""

    def __init__(self) -> None:
        self.server = SimServer(seed=1)
        host, port = self.server.listen_tcp()
        self.url = f"socket://{host}:{port}"
        self._arrived: dict[str, float] = {}
        self._changed = threading.Condition()
        decoder = Decoder()
        deliver = self.server.robot.receive

        def receive(data: bytes, line: Hashable = None) -> None:
            now = time.monotonic()
            deliver(data, line)
            frames = [
                str(event.message)
                for event in decoder.feed(data)
                if isinstance(event, Frame) and isinstance(event.message, Command)
            ]
            if frames:
                with self._changed:
                    for frame in frames:
                        self._arrived[frame] = now
                    self._changed.notify_all()

        self.server.robot.receive = receive  # type: ignore[method-assign]
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self.server.serve, args=(self._stop.is_set,), daemon=True
        )
        self._thread.start()

    def forget(self, frame: str) -> None:
        with self._changed:
            self._arrived.pop(frame, None)

    def wait_for(self, frame: str, timeout_s: float = 5.0) -> float:
        deadline = time.monotonic() + timeout_s
        with self._changed:
            while frame not in self._arrived:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"{frame} did not reach the robot")
                self._changed.wait(remaining)
            return self._arrived[frame]

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5)
        self.server.close()


@contextmanager
def station(robot_url: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    environment = dict(os.environ)
    environment["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + environment.get("PYTHONPATH", "")
    command = [sys.executable, "-m", "rovlink", "web", robot_url, "--port", "0"]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, env=environment)
    try:
        assert process.stdout is not None
        with selectors.DefaultSelector() as selector:
            selector.register(process.stdout, selectors.EVENT_READ)
            if not selector.select(30):
                raise RuntimeError("rovlink web did not start")
        line = process.stdout.readline()
        yield process, _URL.findall(line)[-1]
    finally:
        process.terminate()
        process.wait(10)


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def axes_for(direction_deg: int) -> tuple[list[float], str]:
    """Left-stick axes for a full deflection toward ``direction_deg``, and the frame expected."""
    radians = math.radians(direction_deg)
    x, y = math.sin(radians), math.cos(radians)
    shown = round(math.degrees(math.atan2(x, y)) + 360) % 360
    return [x, -y, 0.0, 0.0], f"#th.{shown}.100!"


def directions(count: int) -> list[int]:
    # Each differs from the one before, so each change is a new frame on the wire.
    return [(17 + index * 37) % 360 for index in range(count)]


def percentile(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(fraction * len(ordered)) - 1)]


def summary(name: str, values_ms: list[float]) -> str:
    return (
        f"{name:<34} p50 {statistics.median(values_ms):6.2f} ms   "
        f"p99 {percentile(values_ms, 0.99):6.2f} ms   max {max(values_ms):6.2f} ms"
    )


def measure_latency(robot: RecordedRobot, url: str, changes: int) -> dict[str, list[float]]:
    results: dict[str, list[float]] = {
        "browser": [],
        "browser, back to back": [],
        "websocket": [],
        "driver": [],
    }
    ws_url = "ws" + url[len("http") :] + "ws"
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        page = browser.new_context(bypass_csp=True).new_page()
        page.add_init_script(FAKE_GAMEPAD)
        page.goto(url)
        page.wait_for_function("window.rovlinkStation && window.rovlinkStation.station.id")
        page.evaluate("fakePads.connect()")
        page.click("#take-control")
        page.wait_for_selector("#control.pilot")
        page.click("#unlock")
        robot.wait_for("#start!")
        page.evaluate("fakePads.set(0, {buttons: {4: true}})")  # the dead-man, held throughout
        page.wait_for_function("window.rovlinkStation.station.telemetry.relay.status === 'flying'")
        for name, spacing_s in (("browser", SPACING_S), ("browser, back to back", 0.0)):
            for direction_deg in directions(changes):
                axes, frame = axes_for(direction_deg)
                robot.forget(frame)
                time.sleep(spacing_s)
                started = time.monotonic()
                page.evaluate("(axes) => fakePads.set(0, {axes})", axes)
                results[name].append((robot.wait_for(frame) - started) * 1e3)
        page.evaluate("fakePads.set(0, {buttons: {4: false}})")
        page.click("#release-control")
        time.sleep(0.3)
        # The same changes from a WebSocket client: no browser, the server and the driver.
        with ws_connect(ws_url, max_size=None) as socket:
            socket.send(json.dumps({"type": "take_control"}))
            pad_ms = 1.0

            def send_input(deadman: bool, direction_deg: int = 0, power: int = 0) -> None:
                nonlocal pad_ms
                pad_ms += 1.0
                socket.send(
                    json.dumps(
                        {
                            "type": "input",
                            "deadman": deadman,
                            "direction_deg": direction_deg,
                            "power_percent": power,
                            "vertical_percent": 0,
                            "pad_timestamp_ms": pad_ms,
                        }
                    )
                )

            send_input(False)
            for direction_deg in directions(changes):
                _, frame = axes_for(direction_deg)
                shown = int(frame.split(".")[1])
                robot.forget(frame)
                time.sleep(SPACING_S)
                started = time.monotonic()
                send_input(True, shown, 100)
                results["websocket"].append((robot.wait_for(frame) - started) * 1e3)
                while True:  # keep the server's outbox from growing: read what is waiting
                    try:
                        socket.recv(timeout=0)
                    except TimeoutError:
                        break
            send_input(False)
        browser.close()
    return results


async def driver_latency(robot: RecordedRobot, changes: int) -> list[float]:
    samples: list[float] = []
    async with rovlink.aio.connect(robot.url, motion_timeout=None) as rov:
        await rov.start()
        for direction_deg in directions(changes):
            _, frame = axes_for(direction_deg)
            shown = int(frame.split(".")[1])
            robot.forget(frame)
            started = time.monotonic()
            await rov.move(shown, 100)
            samples.append((await asyncio.to_thread(robot.wait_for, frame) - started) * 1e3)
        await rov.stop()
    return samples


def measure_cpu(robot_url: str, seconds: float, pages: int) -> tuple[float, list[float]]:
    with station(robot_url) as (process, url), sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        opened = []
        for _ in range(pages):
            page = browser.new_context(bypass_csp=True).new_page()
            page.goto(url)
            page.wait_for_function("window.rovlinkStation && window.rovlinkStation.station.id")
            opened.append(page)
        time.sleep(2.0)  # settle
        counts = [page.evaluate("window.rovlinkStation.station.telemetryCount") for page in opened]
        cpu_before, wall_before = cpu_seconds(process.pid), time.monotonic()
        time.sleep(seconds)
        cpu_after, wall_after = cpu_seconds(process.pid), time.monotonic()
        wall = wall_after - wall_before
        rates = [
            (page.evaluate("window.rovlinkStation.station.telemetryCount") - count) / wall
            for page, count in zip(opened, counts, strict=True)
        ]
        browser.close()
    return (cpu_after - cpu_before) / wall * 100, rates


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--changes", type=int, default=1000)
    parser.add_argument("--cpu-seconds", type=float, default=30.0)
    args = parser.parse_args()
    robot = RecordedRobot()
    try:
        with station(robot.url) as (_, url):
            results = measure_latency(robot, url, args.changes)
        # The robot takes one client at a time: the driver connects once the station is gone.
        results["driver"] = asyncio.run(driver_latency(robot, args.changes))
        print(f"gamepad to wire, {args.changes} changes each (robot: {robot.url})")
        print(summary("browser → server → wire", results["browser"]))
        print(summary("the same, back to back", results["browser, back to back"]))
        print(summary("websocket client → server → wire", results["websocket"]))
        print(summary("driver move() → wire", results["driver"]))
        browser_p99 = percentile(results["browser"], 0.99)
        ratio = browser_p99 / percentile(results["driver"], 0.99)
        met = "met" if browser_p99 <= TARGET_P99_MS else "NOT met"
        print(f"browser p99 / driver p99: {ratio:.1f}×; target p99 ≤ {TARGET_P99_MS:g} ms: {met}")
        idle_cpu, _ = measure_cpu(robot.url, args.cpu_seconds, 0)
        five_cpu, rates = measure_cpu(robot.url, args.cpu_seconds, 5)
        print(f"\nstation CPU over {args.cpu_seconds:g} s, % of one core (telemetry at 10 Hz)")
        print(f"no page open:     {idle_cpu:5.2f} %")
        print(f"five pages open:  {five_cpu:5.2f} %  ({five_cpu / idle_cpu:.2f}× no page)")
        print("telemetry per page: " + ", ".join(f"{rate:.1f} Hz" for rate in rates))
        met = five_cpu < TARGET_CPU_PERCENT
        print(f"target < {TARGET_CPU_PERCENT:g} % of one core: {'met' if met else 'NOT met'}")
    finally:
        robot.close()


if __name__ == "__main__":
    main()
