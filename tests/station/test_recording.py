"""The station's record button over real sockets: the pilot starts and stops a recording of the
robot's link, every page sees it, the finished file downloads and reads back; closing the
station finishes a running recording."""

from __future__ import annotations

import asyncio
import signal
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from rovlink.recorder import FrameEntry, read_entries
from tests.station.page_socket import PageSocket
from tests.station.rig import ControllerLine, running_station

pytestmark = pytest.mark.integration


def _download(url: str) -> tuple[int, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=5) as response:
            return int(response.status), response.read()
    except urllib.error.HTTPError as error:
        return error.code, b""


async def test_the_pilot_records_and_any_page_downloads(line: ControllerLine, tmp_path: Path):
    with running_station(line.url, "--recordings", str(tmp_path)) as served:
        pilot = await PageSocket.open(served.ws_url)
        watcher = await PageSocket.open(served.ws_url)
        assert pilot.hello["recording"]["active"] is False
        await watcher.send({"type": "record_start"})
        refused = await watcher.next("error")
        assert "only the pilot may start or stop a recording" in refused["message"]

        await pilot.send({"type": "take_control"})
        await pilot.next("control", lambda m: m["pilot_id"] == pilot.id)
        await pilot.send({"type": "record_start"})
        started = await watcher.next("recording", lambda m: m["active"])
        name = started["file"]
        assert name.endswith(".mcap")
        mark = line.mark()
        await pilot.send({"type": "command", "name": "mvd", "values": [120]})
        await asyncio.to_thread(line.wait_for, "#mvd.120!", after=mark)
        # A sensor poll while recording, and the one after it: by then the first is recorded
        # (a loaded machine may let a short recording go by without any).
        await asyncio.to_thread(line.wait_for, "#qsa!", after=mark)
        await asyncio.to_thread(line.wait_for, "#qsa!", after=line.mark())
        await pilot.send({"type": "record_start"})
        # (The mvd before it was refused by the controller too, as the robot is locked.)
        await pilot.next("error", lambda m: "already recording" in m["message"])
        await pilot.send({"type": "record_stop"})
        stopped = await watcher.next("recording", lambda m: not m["active"])
        assert [item["name"] for item in stopped["finished"]] == [name]

        status, data = await asyncio.to_thread(_download, served.base + f"recordings/{name}")
        assert status == 200
        for bad in ("nothing.mcap", "..%2F..%2Fetc%2Fpasswd", "%2Fetc%2Fpasswd"):
            assert (await asyncio.to_thread(_download, served.base + f"recordings/{bad}"))[0] in (
                404,
                403,
            )
        await pilot.close()
        await watcher.close()
    downloaded = tmp_path / "downloaded.mcap"
    downloaded.write_bytes(data)
    entries = list(read_entries(str(downloaded)))
    sent = [e.name for e in entries if isinstance(e, FrameEntry) and e.direction == "out"]
    assert "mvd" in sent
    assert "qsa" in sent  # the station's sensor polls are in it too
    assert downloaded.read_bytes() == (tmp_path / name).read_bytes()


async def test_closing_the_station_finishes_a_running_recording(
    line: ControllerLine, tmp_path: Path
):
    with running_station(line.url, "--recordings", str(tmp_path)) as served:
        pilot = await PageSocket.open(served.ws_url)
        await pilot.send({"type": "take_control"})
        await pilot.next("control", lambda m: m["pilot_id"] == pilot.id)
        await pilot.send({"type": "command", "name": "start"})
        await pilot.send({"type": "record_start"})
        name = (await pilot.next("recording", lambda m: m["active"]))["file"]
        await pilot.close()
        served.process.send_signal(signal.SIGTERM)
        await asyncio.to_thread(served.process.wait, 20)
    entries = list(read_entries(str(tmp_path / name)))  # whole: no damage raised
    sent = [e.name for e in entries if isinstance(e, FrameEntry) and e.direction == "out"]
    assert sent[-1] == "stop"  # the station's #stop! on the way out is the last thing in it
