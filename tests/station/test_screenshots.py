"""The screenshots of docs/station.md (``docs/station/*.png``), taken of ``rovlink web`` on a
simulated robot in Debian's chromium, each of a scene staged for it. Run only when asked for
(deselected otherwise, see conftest.py):

    ROVLINK_SCREENSHOTS=1 .venv/bin/python -m pytest -q tests/station/test_screenshots.py

Each scene also checks what it shows, so a screenshot is never of a page that went wrong."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.station.rig import ControllerLine, StationProcess
from tests.station.test_page import (
    Page,
    browser,  # noqa: F401  (the fixture)
    open_page,
    piloting_by_pad,
    set_pad,
)

pytestmark = [pytest.mark.integration, pytest.mark.screenshots]

SCREENSHOTS = Path(__file__).resolve().parents[2] / "docs" / "station"
#: How deep the pilot's scene dives (cm): enough for the charts to show the descent.
DIVE_TARGET_CM = 60


def screenshot(page: Page, name: str, *, full_page: bool) -> None:
    """``docs/station/NAME.png``: the page from its top, as it stands (no toast, no focus ring,
    the leak banner's flashing stopped)."""
    page.evaluate(
        "() => { document.activeElement?.blur(); scrollTo(0, 0);"
        " document.getElementById('toast').hidden = true; }"
    )
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(
        path=str(SCREENSHOTS / f"{name}.png"), full_page=full_page, animations="disabled"
    )


def test_pilot_png_a_dive_with_the_depth_held(
    browser,  # noqa: F811
    station: StationProcess,
    line: ControllerLine,
) -> None:
    page = piloting_by_pad(browser, station, line)
    page.fill("#target-depth", str(DIVE_TARGET_CM))
    mark = line.mark()
    page.press("#target-depth", "Enter")
    line.wait_for(f"#mvd.{DIVE_TARGET_CM}!", after=mark)
    page.click(".log h2")  # out of the field: the pad flies again
    set_pad(page, axes=[0.5, -0.6, 0, 0], deadman=True)
    page.wait_for_function(
        f"window.rovlinkStation.station.telemetry.sensors.depth_cm >= {DIVE_TARGET_CM - 5}",
        timeout=60_000,
    )
    assert page.text_content("#relay-state") == "flying"
    screenshot(page, "pilot", full_page=True)
    page.context.close()


def test_leak_png_the_alarm_on_the_pilots_page(
    browser,  # noqa: F811
    station: StationProcess,
    line: ControllerLine,
) -> None:
    page = piloting_by_pad(browser, station, line)
    line.server.robot.inject_leak()
    page.wait_for_selector("#leak-alarm", state="visible")
    page.wait_for_function(
        "[...document.querySelectorAll('#log li.alarm')]"
        ".some(li => li.textContent.includes('LEAK'))"
    )
    screenshot(page, "leak", full_page=False)
    page.context.close()


def test_watcher_png_a_page_whose_control_was_taken(
    browser,  # noqa: F811
    station: StationProcess,
    line: ControllerLine,
) -> None:
    first = piloting_by_pad(browser, station, line)
    mark = line.mark()
    set_pad(first, axes=[0, -1, 0, 0], deadman=True)
    line.wait_for("#th.0.100!", after=mark)
    second = open_page(browser, station, pad=False)
    second.click("#take-control")
    second.click("#take-control-yes")
    second.wait_for_selector("#control.pilot")
    first.wait_for_selector("#flight-status:has-text('you are no longer the pilot')")
    set_pad(first, deadman=False)
    screenshot(first, "watcher", full_page=False)
    first.context.close()
    second.context.close()
