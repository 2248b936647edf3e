"""The pilot's page in a real browser (Debian's chromium through Playwright) against
``rovlink web`` and a simulated robot; a fake gamepad is injected before the page loads. Every
assertion is on the frames that reach the simulated controller, or on what the page shows."""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import pytest

import rovlink
from rovlink.station.hub import TELEMETRY_LOST_S
from tests.station.rig import (
    CHROMIUM,
    CHROMIUM_ARGS,
    ControllerLine,
    StationProcess,
    running_station,
)
from tests.station.stalling_link import stalling_link

pytestmark = pytest.mark.integration

playwright_api = pytest.importorskip(
    "playwright.sync_api", reason="playwright is not installed: pip install -e '.[test]'"
)
if not os.path.exists(CHROMIUM):
    pytest.skip(
        "chromium is not installed: apt-get install chromium (CI installs it)",
        allow_module_level=True,
    )

FAKE_GAMEPAD = (Path(__file__).parent / "fake_gamepad.js").read_text(encoding="utf-8")
CUT_WITHIN_S = 0.5
DEADMAN, UNLOCK, STOP_BUTTON, CLAW_OPEN, CLAW_CLOSE, MODE = 4, 0, 1, 2, 3, 9

Page = Any


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with playwright_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


def open_page(
    browser: Any, station: StationProcess, *, pad: bool = True, fake_clock: bool = False
) -> Page:
    """A page of the station; with ``fake_clock``, its timers run on Playwright's clock (time
    flows as usual until a test moves it by hand with ``page.clock.run_for``)."""
    # bypass_csp: the page forbids eval, which wait_for_function("...") uses.
    context = browser.new_context(viewport={"width": 1400, "height": 1000}, bypass_csp=True)
    context.add_init_script(FAKE_GAMEPAD)
    if fake_clock:
        context.clock.install()
    page = context.new_page()
    page.goto(station.url)
    page.wait_for_function("window.rovlinkStation && window.rovlinkStation.station.id !== null")
    if pad:
        page.evaluate("fakePads.connect()")
    return page


def take_control(page: Page) -> None:
    page.click("#take-control")
    page.wait_for_selector("#control.pilot")


def set_pad(
    page: Page,
    *,
    axes: list[float] | None = None,
    buttons: dict[str, bool] | None = None,
    **named: bool,
) -> float:
    """Set the fake pad's axes and buttons (by name: ``deadman=True``, ``claw_open=False``)."""
    pressed = {**(buttons or {}), **named}
    numbered = {str(globals()[name.upper()]): down for name, down in pressed.items()}
    script = "([axes, buttons]) => fakePads.set(0, {axes, buttons})"
    return float(page.evaluate(script, [axes, numbered]))


def unlock_and_arm(page: Page, line: ControllerLine) -> None:
    mark = line.mark()
    set_pad(page, unlock=True)
    line.wait_for("#start!", after=mark)
    set_pad(page, unlock=False)
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.relay.status.startsWith('armed')"
    )


def piloting_by_pad(browser, station, line) -> Page:
    """A pilot's page on the fake pad, the robot unlocked and the relay armed."""
    page = open_page(browser, station)
    take_control(page)
    unlock_and_arm(page, line)
    return page


def flying_by_pad(browser, station, line, axes: list[float], frame: str) -> Page:
    """:func:`piloting_by_pad`, the sticks at ``axes`` with the dead-man held, once the
    controller got their ``frame``."""
    page = piloting_by_pad(browser, station, line)
    mark = line.mark()
    set_pad(page, axes=axes, deadman=True)
    line.wait_for(frame, after=mark)
    return page


# The command messages the page sends from now on, kept in window.commandsSent.
COMMANDS_SENT = """() => { const connection = window.rovlinkStation.connection;
  const send = connection.send.bind(connection); window.commandsSent = [];
  connection.send = (m) => {
    if (m.type === 'command') window.commandsSent.push(m); return send(m); };
}"""
# The input messages the page sends from now on, kept in window.inputsSent.
INPUTS_SENT = """() => { const connection = window.rovlinkStation.connection;
  const send = connection.send.bind(connection); window.inputsSent = [];
  connection.send = (m) => { if (m.type === 'input') window.inputsSent.push(m); return send(m); };
}"""


@pytest.mark.realtime
def test_stick_right_with_the_dead_man_drives_and_release_stops(browser, station, line):
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    page.wait_for_function("window.rovlinkStation.station.telemetry.relay.status === 'flying'")
    page.evaluate(INPUTS_SENT)
    mark = line.mark()
    set_pad(page, deadman=False)
    line.wait_for("#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S * 2)
    # Each input carries the page's clock: the station measures how late it arrives.
    assert page.evaluate("window.inputsSent.map(m => typeof m.sent_ms)")[:1] == ["number"]
    page.context.close()


def test_pad_buttons_claw_mode_and_the_vertical_stick(browser, station, line):
    page = piloting_by_pad(browser, station, line)
    for button, frame in (("claw_open", "#h+!"), ("claw_close", "#h-!"), ("mode", "#mvdirect.1!")):
        mark = line.mark()
        set_pad(page, buttons={button: True})
        line.wait_for(frame, after=mark)
        set_pad(page, buttons={button: False})
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.commanded.vertical_mode === 'direct'"
    )
    mark = line.mark()
    set_pad(page, axes=[0, 0, 0, -1], deadman=True)  # right stick up: + is up
    line.wait_for("#mvs.+100!", after=mark)
    mark = line.mark()
    set_pad(page, deadman=False)
    line.wait_for("#mvs.+0!", after=mark)
    page.context.close()


def test_no_thrust_without_the_dead_man(browser, station, line):
    page = piloting_by_pad(browser, station, line)
    mark = line.mark()
    set_pad(page, axes=[0, -1, 0, 0])  # full ahead, dead-man not held
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.power_percent === 100")
    # Nor the dead-man pressed as the answer to *learn* ("that press does nothing else"), while
    # learning or held on after it (before, it flew at once).
    page.click("[data-learn='claw_open']")
    set_pad(page, axes=[0, -1, 0, 0], deadman=True)
    page.wait_for_function(
        "JSON.parse(localStorage.getItem('rovlink.mapping') || '{}').buttons?.claw_open === 4"
    )
    page.wait_for_function(  # the page polled the held dead-man after learning
        "!window.rovlinkStation.devices.learning"
        " && window.rovlinkStation.devices.lastInput?.deadman === false",
        timeout=2000,
    )
    set_pad(
        page, axes=[0, -1, 0, 0], deadman=True, stop_button=True
    )  # a fence: STOP reaches the robot
    line.wait_for("#stop!", after=mark)
    assert not [frame for frame in line.frames(mark) if frame.startswith("#th.0.")]
    page.context.close()


@pytest.mark.realtime
def test_a_frozen_pad_zeroes_the_thrust_within_500_ms(browser, station, line):
    page = flying_by_pad(browser, station, line, [0, -1, 0, 0], "#th.0.100!")
    mark = line.mark()
    page.evaluate("fakePads.freeze(0)")
    frozen_s = time.monotonic()
    zero = line.wait_for("#th.0.0!", after=mark)
    assert zero.at_s - frozen_s < CUT_WITHIN_S
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.relay.status.includes('gamepad reported nothing')"
    )
    page.context.close()


@pytest.mark.realtime
def test_a_page_whose_script_stalls_zeroes_the_thrust_within_500_ms(browser, station, line):
    page = flying_by_pad(browser, station, line, [0, -1, 0, 0], "#th.0.100!")
    mark = line.mark()
    # The page's script stalls for a second (a long task, a browser busy elsewhere): it sends
    # nothing, its socket stays open.
    page.evaluate(
        "setTimeout(() => { const t = performance.now(); while (performance.now() - t < 1000); })"
    )
    stalled_s = time.monotonic()
    zero = line.wait_for("#th.0.0!", after=mark)
    assert zero.at_s - stalled_s < CUT_WITHIN_S
    # Awake again with the dead-man still held: nothing moves until it is released and pressed.
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.deadman === true")
    page.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    assert "#th.0.100!" not in line.frames(mark)
    page.context.close()


def test_a_pilot_whose_computer_slept_flies_again_once_the_dead_man_is_pressed_again(
    browser, station, line
):
    page = open_page(browser, station, fake_clock=True)
    take_control(page)
    unlock_and_arm(page, line)
    mark = line.mark()
    set_pad(page, axes=[1, 0, 0, 0], deadman=True)
    line.wait_for("#th.90.100!", after=mark)
    # The pilot's computer sleeps (the station's does not): the page's timers stop, and so does
    # performance.now(), which Chrome on Linux and macOS does not advance while asleep.
    page_now = datetime.fromtimestamp(page.evaluate("Date.now()") / 1000)
    page.clock.pause_at(page_now + timedelta(milliseconds=100))
    asleep = line.mark()
    line.wait_for("#th.90.0!", after=asleep)  # (the station's watchdog)
    # Ten polls: the station's clock went on for 0.9 s at least, well over the 300 ms an
    # input may arrive late.
    line.wait_until(lambda: line.frames(asleep).count("#qsa!") >= 10)
    # It wakes: the wall clock is right again, the steady clock goes on from where it stood.
    page.clock.set_system_time(datetime.now())
    page.clock.resume()
    # Before, every input seemed to arrive as late as the sleep was long, for good: the
    # release did not arm the relay, and the pilot could not fly again on that connection.
    set_pad(page, deadman=False)
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.relay.status.startsWith('armed')",
        timeout=5000,
    )
    woke = line.mark()
    set_pad(page, deadman=True)
    line.wait_for("#th.90.100!", after=woke)
    set_pad(page, deadman=False)
    page.context.close()


@pytest.mark.realtime
def test_closing_the_tab_zeroes_the_thrust_within_500_ms(browser, station, line):
    page = flying_by_pad(browser, station, line, [-1, 0, 0, 0], "#th.270.100!")
    mark = line.mark()
    closed_s = time.monotonic()
    page.close()
    zero = line.wait_for("#th.270.0!", after=mark)
    assert zero.at_s - closed_s < CUT_WITHIN_S


@pytest.mark.realtime
def test_unplugging_the_pad_zeroes_the_thrust(browser, station, line):
    page = flying_by_pad(browser, station, line, [0, 1, 0, 0], "#th.180.100!")
    mark = line.mark()
    unplugged_s = time.monotonic()
    page.evaluate("fakePads.disconnect(0)")
    zero = line.wait_for("#th.180.0!", after=mark)
    assert zero.at_s - unplugged_s < CUT_WITHIN_S
    page.wait_for_selector("#device-status:has-text('no gamepad')")
    page.context.close()


@pytest.mark.realtime
def test_a_page_whose_socket_drops_reconnects_as_a_watcher(browser, station, line):
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    page.wait_for_function("window.rovlinkStation.charts.columns[0].length > 3")
    mark = line.mark()
    page.evaluate("window.rovlinkStation.connection.socket.close()")
    line.wait_for("#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S * 2)
    page.wait_for_function("window.rovlinkStation.station.id === 'p2'")  # the new hello
    page.wait_for_selector("#control-status:has-text('nobody has control')")
    assert "no longer the pilot: the connection to the station dropped" in page.text_content(
        "#flight-status"
    )
    times = page.evaluate("window.rovlinkStation.charts.columns[0]")
    assert times == sorted(set(times))  # the history once, in order
    assert "#th.90.100!" not in line.frames(mark)  # the held pad does not fly a watcher
    # The station closes (SIGTERM): the page says so, not that the connection dropped.
    set_pad(page, deadman=False)
    take_control(page)
    station.process.terminate()
    page.wait_for_selector(
        "#flight-status:text-is('you are no longer the pilot: the station closed')", timeout=5000
    )
    assert page.text_content("#connection") == "the station closed: reconnecting when it is back"
    assert page.text_content("#stale-banner") == "the station closed: everything shown is old"
    page.context.close()


def test_a_page_that_cannot_reach_the_station_does_not_say_who_has_control(browser, line, tmp_path):
    with running_station(line.url, "--recordings", str(tmp_path)) as served:
        page = open_page(browser, served, pad=False)
        take_control(page)
        page.click("#record")
        page.wait_for_selector("#recording.active")
        # The station cannot be reached: the socket drops and no new one opens.
        page.evaluate(
            "const c = window.rovlinkStation.connection; c.open = () => {}; c.socket.close()"
        )
        page.wait_for_selector("body.stale")
        # Before, it read "watching: nobody has control", and the recording's time stood
        # still at full strength, as live.
        assert page.text_content("#control-status") == (
            "not connected: who has control is not known"
        )
        opacity = page.eval_on_selector("#recording-status", "e => getComputedStyle(e).opacity")
        assert float(opacity) < 1
        page.context.close()


def test_a_page_whose_token_is_no_longer_taken_says_so(browser, line):
    with running_station(line.url, "--token", "deck-token-1") as served:
        # (The URL's token set its cookie.) On Playwright's clock: the retries are hurried.
        page = open_page(browser, served, pad=False, fake_clock=True)
        # The token is no longer taken (as when the station restarted with a new one): before,
        # the page said "reconnecting" for ever, the browser hiding the station's refusal.
        page.context.clear_cookies()
        page.evaluate("window.rovlinkStation.connection.socket.close()")
        page.wait_for_selector("#stale-banner:has-text('the station refuses this page')")
        assert "a token is needed: open the URL that rovlink web printed" in page.text_content(
            "#stale-banner"
        )
        assert page.text_content("#connection") == "refused by the station"
        # The URL with the token again: the next attempt is taken, and the refusal is no more.
        page.context.new_page().goto(served.url)
        page.clock.run_for(5000)  # (the longest wait between two attempts)
        page.wait_for_function("window.rovlinkStation.connection.isOpen")
        assert "refuses" not in page.text_content("#stale-banner")
        page.context.close()


# Every text the toast shows from now on, in window.toastsShown (one may follow another at once).
TOASTS_SHOWN = """() => { const toast = document.getElementById('toast'); window.toastsShown = [];
  new MutationObserver(() => window.toastsShown.push(toast.textContent))
    .observe(toast, {childList: true, characterData: true, subtree: true}); }"""


def test_stop_pressed_while_the_station_cannot_be_reached_goes_first_on_reconnecting(
    browser, station, line
):
    page = open_page(browser, station, pad=False)
    take_control(page)
    mark = line.mark()
    page.click("#unlock")
    line.wait_for("#start!", after=mark)
    # The socket drops and STOP is pressed before the page has reconnected (in one script:
    # the page cannot reconnect in between). Before, the STOP was dropped without a word.
    page.evaluate(TOASTS_SHOWN)
    page.evaluate(
        "window.rovlinkStation.connection.socket.close(); document.getElementById('stop').click()"
    )
    line.wait_for("#stop!", after=mark)
    line.wait_until(lambda: line.controller_locked)
    page.wait_for_function("window.toastsShown.some(text => text.startsWith('STOP sent'))")
    shown = page.evaluate("window.toastsShown")
    assert shown[0].startswith("STOP not sent yet")
    assert line.frames(mark, commands_only=True).count("#stop!") == 1  # (kept, and its own)
    page.wait_for_function("window.rovlinkStation.station.id === 'p2'")  # reconnected
    # Anything else that cannot be sent says so; it is not kept (it would act later, unasked).
    page.evaluate(
        "window.rovlinkStation.connection.socket.close();"
        " document.getElementById('take-control').click()"
    )
    page.wait_for_selector("#toast:has-text('not connected to the station: taking control')")
    page.wait_for_function("window.rovlinkStation.station.id === 'p3'")
    page.click("#stop")  # a fence: its log entry comes after anything sent before it
    page.wait_for_selector("#log li:has-text('STOP from browser 3')")
    assert page.text_content("#control-status") == "watching: nobody has control"
    page.context.close()


@pytest.mark.slow  # (the station gives the dead connection up after its pings: some 10 s)
def test_stop_pressed_while_the_network_is_gone_is_kept_until_the_station_takes_it(
    browser, station, line
):
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    watcher = open_page(browser, station, pad=False)
    # The network goes (a Wi-Fi gone): the page's socket still reads open and takes what is
    # sent on it, and the STOP's own socket cannot connect.
    mark = line.mark()
    page.context.set_offline(True)
    line.wait_for("#th.90.0!", after=mark)  # (the station's watchdog: the page is not heard)
    page.click("#stop")
    # Before, nothing was said, and the STOP went nowhere: the motors stayed unlocked.
    page.wait_for_selector("#toast:has-text('STOP not confirmed: the station cannot be reached')")
    # The station gives that connection up (its pings), and the STOP sent on it with it.
    watcher.wait_for_selector(
        "#log li:has-text('browser 1 (127.0.0.1) disconnected')", timeout=15000
    )
    assert "#stop!" not in line.frames(mark)
    page.context.set_offline(False)
    line.wait_for("#stop!", after=mark)
    line.wait_until(lambda: line.controller_locked)
    page.wait_for_selector("#toast:has-text('STOP sent')")
    assert line.frames(mark, commands_only=True).count("#stop!") == 1  # (taken once)
    set_pad(page, deadman=False)
    page.context.close()
    watcher.context.close()


@pytest.mark.realtime
def test_stop_pressed_on_a_connection_that_stopped_carrying_anything_gets_through(
    browser, station, line
):
    port = int(station.base.rstrip("/").rsplit(":", 1)[1])
    with stalling_link(port) as link:
        page = flying_by_pad(
            browser, StationProcess(station.process, link.url), line, [1, 0, 0, 0], "#th.90.100!"
        )
        mark = line.mark()
        # The network stops carrying what this page sends on its socket (a Wi-Fi that roamed:
        # the old connection is dead, and neither end knows it yet); the station hears nothing.
        link.stall_open_connections()
        line.wait_for("#th.90.0!", after=mark)  # (the station's watchdog)
        pressed_s = time.monotonic()
        page.click("#stop")
        # Before, the STOP waited on the dead socket, and was lost with it when the station
        # gave the connection up (10 s): the motors stayed unlocked.
        stopped = line.wait_for("#stop!", after=mark, timeout_s=3.0)
        assert stopped.at_s - pressed_s < CUT_WITHIN_S
        page.wait_for_selector("#log li:has-text('STOP from browser 1')")
        set_pad(page, deadman=False)
        page.context.close()


#: The accessibility tree's roles of what a person operates on the page.
CONTROL_ROLES = ("button", "spinbutton", "textbox", "checkbox", "slider", "link", "combobox")
#: The watcher's page: what only the pilot may use.
PILOT_ONLY = ".pilot-only button, .pilot-only input, #settings-rows button, #settings-rows input"


def accessible_controls(page: Page) -> list[tuple[str, str, bool]]:
    """Every control in the page's accessibility tree (as a screen reader gets it): its role,
    its name and whether it is disabled."""
    session = page.context.new_cdp_session(page)
    nodes = session.send("Accessibility.getFullAXTree")["nodes"]
    session.detach()
    controls = []
    for node in nodes:
        role = node.get("role", {}).get("value")
        if node.get("ignored") or role not in CONTROL_ROLES:
            continue
        properties = {item["name"]: item["value"].get("value") for item in node["properties"]}
        name = str(node.get("name", {}).get("value", "")).strip()
        controls.append((role, name, bool(properties.get("disabled"))))
    return controls


def test_every_control_is_named_and_a_watchers_pilot_controls_are_disabled(browser, station, line):
    page = open_page(browser, station)
    page.click("#settings-panel summary")  # its fields in the tree too
    page.wait_for_selector("#setting-mgmp", state="visible")
    controls = accessible_controls(page)
    assert len(controls) > 40
    # Each has a name of its own (before: 15 number fields without one, six "Send", six
    # "learn" and three "invert" that did not say what for).
    nameless = [role for role, name, _ in controls if not name]
    assert not nameless, f"{len(nameless)} controls without a name: {nameless}"
    named = [(role, name) for role, name, _ in controls]
    assert len(set(named)) == len(named), sorted(n for n in named if named.count(n) > 1)
    # A watcher's pilot controls are disabled, as a screen reader and the keyboard get them
    # (before, only greyed out for the mouse: Tab and Enter pressed them).
    watched = page.locator(PILOT_ONLY).evaluate_all("els => els.map(el => el.disabled)")
    assert len(watched) > 10
    assert all(watched)
    disabled = {name for _, name, off in controls if off}
    assert {"Unlock (#start!)", "Claw open", "Hold"} <= disabled
    # The pilot's page: enabled; the instruments are images named by what they show, and
    # why nothing moves (a cut and its reason) is announced.
    take_control(page)
    assert not any(page.locator(PILOT_ONLY).evaluate_all("els => els.map(el => el.disabled)"))
    assert page.get_attribute("#flight-status", "role") == "status"
    for canvas in ("attitude", "depth", "thrust vector", "heading"):
        assert page.get_by_role("img", name=canvas, exact=True).count() == 1
    page.context.close()


def choose_device(page: Page, value: str) -> None:
    """Choose the input device (``keyboard``, ``auto``, ``pad:ID``) under *Input device*."""
    page.click(f"#device-choice button[data-device='{value}']")
    page.wait_for_selector(f"#device-choice button[data-device='{value}'][aria-pressed='true']")


def take_control_from_another(page: Page) -> None:
    """Take control while another page has it: the page asks first, and is answered yes."""
    page.click("#take-control")
    page.click("#take-control-yes")
    page.wait_for_selector("#control.pilot")


def stop_key_reaches_the_robot(page: Page, line: ControllerLine, key: str, where: str) -> None:
    mark = line.mark()
    page.keyboard.press(key)
    try:
        line.wait_for("#stop!", after=mark)
    except AssertionError:
        raise AssertionError(f"{key} with {where} did not stop the robot") from None
    # Only the STOP: the key did nothing else (no click on a focused button).
    line.wait_until(lambda: line.frames(mark, commands_only=True) == ["#stop!"], timeout_s=0.2)


# STOP on screen, nothing over it (its centre and corners), and no sideways scroll.
STOP_REACHABLE = """() => {
  const box = document.getElementById('stop').getBoundingClientRect();
  const points = [[(box.left + box.right) / 2, (box.top + box.bottom) / 2],
    [box.left + 4, box.top + 4], [box.right - 4, box.top + 4],
    [box.left + 4, box.bottom - 4], [box.right - 4, box.bottom - 4]];
  return box.left >= 0 && box.right <= innerWidth && box.top >= 0
    && points.every(([x, y]) => document.elementFromPoint(x, y)?.id === 'stop')
    && document.documentElement.scrollWidth <= innerWidth;
}"""


# Everything on the page that can hold the keyboard's focus; a <select> is also clicked open.
FOCUSABLE = "button:not([disabled]), summary, a[href], input, select, textarea, [tabindex]"
VISIBLE = "els => els.map((el, i) => [i, el.offsetParent !== null, el.outerHTML.slice(0, 70)])"
FOCUS = "([selector, index]) => document.querySelectorAll(selector)[index].focus()"
PAGE_STATE = """() => ({
  pilot: document.getElementById('control').classList.contains('pilot'),
  recording: document.getElementById('recording').classList.contains('active'),
  open: [...document.querySelectorAll('details')].map(d => d.open),
  ticked: [...document.querySelectorAll('input[type=checkbox]')].map(c => c.checked),
  values: [...document.querySelectorAll('input, select')].map(i => i.value),
  device: localStorage.getItem('rovlink.device'),
})"""


def test_no_control_on_the_page_keeps_the_stop_keys(browser, station, line):
    page = open_page(browser, station)
    take_control(page)
    page.click("#settings-panel summary")  # its fields shown too
    page.wait_for_selector("#setting-mgmp", state="visible")
    before = page.evaluate(PAGE_STATE)
    controls = page.locator(FOCUSABLE)
    checked = 0
    for index, visible, where in controls.evaluate_all(VISIBLE):
        if not visible or where.startswith('<button id="stop"'):
            continue
        # Space activates buttons, boxes and summaries; Esc closes dropdowns and clears fields.
        typed_in = where.startswith(("<select", "<input", "<textarea"))
        for key in ("Space", "Escape") if typed_in else ("Space",):
            if where.startswith("<select"):
                controls.nth(index).click()  # its dropdown opened
            else:
                page.evaluate(FOCUS, [FOCUSABLE, index])
            stop_key_reaches_the_robot(page, line, key, where)
        checked += 1
    assert checked > 20  # (the panels' controls were all there)
    assert page.evaluate(PAGE_STATE) == before  # no key clicked, ticked, opened or chose
    # No field offers the browser's autocomplete list, which takes Esc while open.
    assert page.evaluate(
        "[...document.querySelectorAll('input[type=number]')].every(i => i.autocomplete === 'off')"
    )
    # STOP stays on screen, clear of anything over it, on a narrow window scrolled down.
    for width in (1024, 800):
        page.set_viewport_size({"width": width, "height": 700})
        page.mouse.wheel(0, 2000)
        page.wait_for_function("scrollY > 0")
        assert page.evaluate(STOP_REACHABLE), f"STOP not fully on screen {width} px wide"
    page.context.close()


# The element is on screen, and what is at its centre is itself (nothing lies over it).
ON_SCREEN_UNCOVERED = """(selector) => { const el = document.querySelector(selector);
  const r = el.getBoundingClientRect();
  const inside = r.top >= 0 && r.bottom <= innerHeight && r.left >= 0 && r.right <= innerWidth;
  return inside && el.contains(document.elementFromPoint((r.left + r.right) / 2,
    (r.top + r.bottom) / 2)); }"""


def test_the_stop_button_and_the_stop_keys_send_stop(browser, station, line):
    page = open_page(browser, station, pad=False)
    for press in (
        lambda: page.click("#stop"),
        lambda: page.keyboard.press("Space"),
        lambda: page.keyboard.press("Escape"),
    ):
        mark = line.mark()
        press()
        line.wait_for("#stop!", after=mark)
    page.context.close()


def test_a_leak_shows_the_alarm_and_reset_sends_slreset(browser, station, line):
    page = open_page(browser, station, pad=False)
    assert page.is_hidden("#leak-alarm")
    line.server.robot.inject_leak()
    page.wait_for_selector("#leak-alarm", state="visible")
    # Nobody touched this page yet: the browser plays no sound, and the banner says so (before,
    # it beeped in silence, as if heard).
    assert "no sound until the page is clicked" in page.text_content("#leak-detail")
    page.click("#leak-alarm strong")
    page.wait_for_selector("#leak-detail:not(:has-text('no sound'))")
    # A watcher may silence its own page, not reset the robot's latch (the station refuses).
    assert page.is_disabled("#leak-reset")
    assert page.is_enabled("#leak-silence")
    # The banner stays on screen with the top bar, whatever is scrolled to (the mapping, the
    # settings): before, it went off the top with the instruments.
    page.mouse.wheel(0, 2000)
    page.wait_for_function("scrollY > 0")
    assert page.evaluate(ON_SCREEN_UNCOVERED, "#leak-silence")
    take_control(page)
    assert page.is_enabled("#leak-reset")
    page.wait_for_function(
        "[...document.querySelectorAll('#log li.alarm')]"
        ".some(li => li.textContent.includes('LEAK'))"
    )
    assert page.evaluate("window.rovlinkStation.alarm.playing")  # the beep, every second
    page.click("#leak-silence")
    assert not page.evaluate("window.rovlinkStation.alarm.playing")
    assert page.is_visible("#leak-alarm")  # silenced, still shown: the latch is still set
    mark = line.mark()
    page.click("#leak-reset")
    line.wait_for("#slreset!", after=mark)
    page.wait_for_selector("#leak-alarm", state="hidden")
    page.context.close()


# How much of the window's height the sticky top bar (with the leak banner) takes.
TOP_BAR_SHARE = "document.getElementById('top').getBoundingClientRect().height / innerHeight"
# STOP's width and height (px).
STOP_SIZE = """() => { const r = document.getElementById('stop').getBoundingClientRect();
  return [r.width, r.height]; }"""


def test_a_phone_sized_window_shows_everything_whole_and_readable(browser, station, line):
    page = open_page(browser, station, pad=False)
    # A watcher that lost nothing: no banner under the top bar, and no empty strip in its place.
    assert page.text_content("#flight-status") == ""
    assert page.evaluate("document.getElementById('flight-status').offsetHeight") == 0
    page.set_viewport_size({"width": 390, "height": 844})
    page.wait_for_function(  # (the charts follow the window's width a moment later)
        "document.documentElement.scrollWidth <= innerWidth", timeout=2000
    )
    # The sticky top bar is compact: a sixth of the screen at most (before, a third), its STOP
    # whole, uncovered and big enough to hit, the link's state shown.
    assert page.evaluate(TOP_BAR_SHARE) <= 1 / 6
    assert page.evaluate(STOP_REACHABLE)
    assert page.evaluate(STOP_SIZE) >= [80, 44]
    assert page.evaluate(ON_SCREEN_UNCOVERED, "#connection")
    line.server.robot.inject_leak()
    page.wait_for_selector("#leak-alarm", state="visible")
    # With the leak banner under it: a quarter of the screen at most (before, a half). The
    # banner wraps: its buttons stay in the window, which never scrolls sideways.
    assert page.evaluate(TOP_BAR_SHARE) <= 1 / 4
    assert page.evaluate(STOP_REACHABLE)
    for shown in ("#connection", "#leak-alarm strong", "#leak-silence", "#leak-reset"):
        assert page.evaluate(ON_SCREEN_UNCOVERED, shown), shown
    # A message at the bottom takes the window's width, not half of it (four words a line).
    page.evaluate("window.rovlinkStation.connection.send({type: 'command', name: 'start'})")
    page.wait_for_selector("#toast:has-text('only the pilot')")
    assert page.evaluate(
        "(() => { const r = document.getElementById('toast').getBoundingClientRect();"
        " return r.width > 0.75 * innerWidth && r.left >= 0 && r.right <= innerWidth; })()"
    )
    # The heading tape is drawn for the width it is shown at, not shrunk to half its size
    # (its figures were 6 px high).
    page.wait_for_function(
        "Math.abs(document.getElementById('heading').width"
        " - document.getElementById('heading').getBoundingClientRect().width) < 1",
        timeout=2000,
    )
    # At every heading, each of the tape's labels is drawn whole (before, those at its edges
    # were cut: "00" of 300).
    cut = page.evaluate(HEADING_LABELS_CUT)
    assert not cut, f"labels cut at the tape's edges: {cut[:5]}"
    # The settings' fields, ranges and Send buttons line up, each range on one line (before,
    # "0–" above "99", and every field where its name ended).
    page.click("#settings-panel summary")
    page.wait_for_selector("#setting-mgmp", state="visible")
    assert page.evaluate(SETTINGS_LAYOUT) == {
        "rows": 6,
        "columns": [1, 1, 1],
        "ranges on one line": True,
        "inside the window": True,
    }
    # The smallest phones (320 px) never scroll sideways either: before, the charts kept
    # 300 px whatever the panel's width, and stuck out of it.
    page.set_viewport_size({"width": 320, "height": 568})
    page.wait_for_function(
        "document.documentElement.scrollWidth <= innerWidth"
        " && document.querySelector('#depth-chart canvas').getBoundingClientRect().right"
        " <= document.querySelector('.charts').getBoundingClientRect().right",
        timeout=2000,
    )
    page.context.close()


# The settings rows: how many, how many left edges their fields, ranges and Send buttons have
# (1 each: in columns), whether every range is one line high and everything inside the window.
SETTINGS_LAYOUT = """() => {
  const rows = [...document.querySelectorAll('.setting-row')];
  const lefts = (selector) => new Set(rows.map(
    (row) => Math.round(row.querySelector(selector).getBoundingClientRect().left))).size;
  const ranges = rows.map((row) => row.querySelector('.muted'));
  return {
    rows: rows.length,
    columns: [lefts('input'), lefts('.muted'), lefts('button')],
    'ranges on one line': ranges.every((el) => el.getBoundingClientRect().height
      < 1.5 * parseFloat(getComputedStyle(el).lineHeight)),
    'inside the window': rows.every((row) => [...row.children].every(
      (el) => el.getBoundingClientRect().right <= innerWidth)),
  }; }"""


# The heading tape drawn at every whole heading: the labels that do not lie wholly on it.
HEADING_LABELS_CUT = """async () => {
  const { drawHeading } = await import('/static/js/instruments.js');
  const canvas = document.getElementById('heading');
  const fill = CanvasRenderingContext2D.prototype.fillText;
  const cut = [];
  CanvasRenderingContext2D.prototype.fillText = function (text, x, ...rest) {
    const half = this.measureText(text).width / 2;
    if (this.canvas === canvas && (x - half < 0 || x + half > this.canvas.width)) {
      cut.push([String(text), Math.round(x), this.canvas.width]);
    }
    return fill.call(this, text, x, ...rest);
  };
  try { for (let deg = 0; deg < 360; deg += 1) drawHeading(canvas, deg); }
  finally { CanvasRenderingContext2D.prototype.fillText = fill; }
  return cut; }"""


def test_the_leak_alarm_stays_while_no_reading_says_the_latch_is_clear(browser, station, line):
    page = open_page(browser, station, pad=False)
    page.click(".log h2")  # (a click: the page may sound)
    line.server.robot.inject_leak()
    page.wait_for_selector("#leak-alarm", state="visible")
    assert page.evaluate("window.rovlinkStation.alarm.playing")
    # The robot's link lost (a cable pulled as the hull floods): no readings, the latch as it
    # was last read. Before, the banner went and the beep stopped at the first failed poll.
    line.close()
    page.wait_for_selector("#depth-value:text-is('–')", timeout=10_000)  # a poll failed
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.sensors === null"
        " && window.rovlinkStation.station.telemetryCount > 0"
    )
    assert page.is_visible("#leak-alarm")
    assert "as last read" in page.text_content("#leak-alarm")
    assert page.evaluate("window.rovlinkStation.alarm.playing")
    page.context.close()


def test_a_watcher_is_told_the_robot_holds_a_depth_not_that_it_has_no_thrust(
    browser, station, line
):
    pilot = open_page(browser, station, pad=False)
    take_control(pilot)
    pilot.click("#unlock")
    line.wait_for("#start!")
    pilot.fill("#target-depth", "150")
    pilot.press("#target-depth", "Enter")
    line.wait_for("#mvd.150!")
    watcher = open_page(browser, station, pad=False)
    # (Before: "no thrust", while the depth hold drove the vertical thrusters.)
    watcher.wait_for_selector("#relay-state:text-matches('^holding 150 cm; .* has control$')")
    pilot.click("#stop")
    watcher.wait_for_selector("#relay-state:text-matches('^motors locked; ')")
    watcher.context.close()
    pilot.context.close()


def test_a_second_browser_cannot_command(browser, station, line):
    pilot = open_page(browser, station)
    # Nobody has control: the relay row says so, not the pilot's "release the dead-man to arm"
    # (and the motors as the station left them when it started: locked).
    pilot.wait_for_selector(
        "#relay-state:text-is('motors locked; nobody has control')", timeout=2000
    )
    take_control(pilot)
    watcher = open_page(browser, station)
    watcher.wait_for_function(
        "document.getElementById('control-status').textContent.includes('has control')"
    )
    # A watcher sees what the robot does and who flies; the pilot, what to do.
    watcher.wait_for_selector(
        "#relay-state:text-is('motors locked; browser 1 (127.0.0.1) has control')"
    )
    pilot.wait_for_selector("#relay-state:text-is('motors locked: unlock (#start!) to fly')")
    mark = line.mark()
    set_pad(watcher, axes=[1, 0, 0, 0], deadman=True, unlock=True)
    watcher.click("#claw-open", force=True)  # shown disabled; forced, the server still refuses
    watcher.evaluate("window.rovlinkStation.connection.send({type: 'command', name: 'start'})")
    watcher.wait_for_selector("#toast:has-text('only the pilot')")
    set_pad(pilot, unlock=True)  # a fence from the pilot
    line.wait_for("#start!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#start!"]
    set_pad(pilot, unlock=False, axes=[1, 0, 0, 0], deadman=True)
    line.wait_for("#th.90.100!", after=mark)
    watcher.wait_for_selector(
        "#relay-state.flying:text-is('flying; browser 1 (127.0.0.1) has control')"
    )
    set_pad(pilot, deadman=False)
    line.wait_for("#th.90.0!", after=mark)
    # Taking control is explicit (the watcher is asked, on the page) and both see it.
    watcher.click("#take-control")
    watcher.click("#take-control-no")  # asked, and cancelled: nothing changes
    watcher.wait_for_selector("#take-control-question", state="hidden")
    assert watcher.is_visible("#take-control")
    watcher.click("#take-control")
    watcher.wait_for_selector("#take-control-question:has-text('Take control from browser 1')")
    # The question is no browser dialog, which would stop the page: the STOP keys still work.
    for key in ("Space", "Escape"):
        stop_key_reaches_the_robot(watcher, line, key, "the take-control question shown")
    taken = line.mark()
    watcher.click("#take-control-yes")
    watcher.wait_for_selector("#control.pilot")
    pilot.wait_for_function(
        "document.getElementById('control-status').textContent.startsWith('watching')"
    )
    # The unlock button the watcher held all along is no press: nothing was sent for it.
    set_pad(watcher, deadman=False, unlock=False)
    watcher.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=taken)
    assert "#start!" not in line.frames(taken)
    pilot.context.close()
    watcher.context.close()


# What the station says is held back from the page until deliverHeldMessages() (a slow network).
HOLD_MESSAGES = """() => { const connection = window.rovlinkStation.connection;
  const handle = connection.onMessage; const held = [];
  connection.onMessage = (message) => held.push(message);
  window.deliverHeldMessages = () => { connection.onMessage = handle; held.forEach(handle); };
}"""


def test_two_pages_taking_control_at_once_leave_it_with_the_first_and_ask_the_other(
    browser, station, line
):
    first = open_page(browser, station, pad=False)
    second = open_page(browser, station, pad=False)
    # Both click Take control with nobody in control, each before it hears of the other (what
    # the station says reaches the second page only after its click).
    second.evaluate(HOLD_MESSAGES)
    first.click("#take-control")
    first.wait_for_selector("#control.pilot")
    second.click("#take-control")
    second.evaluate("window.deliverHeldMessages()")
    # Before, the second took it from the first without asking, as the first was taking off.
    second.wait_for_selector("#toast:has-text('took control a moment before: nothing changed')")
    first.wait_for_selector("#control.pilot")
    assert second.text_content("#control-status") == "watching: browser 1 (127.0.0.1) has control"
    # Taking it now asks first, as from any pilot.
    take_control_from_another(second)
    first.wait_for_selector("#control-status:has-text('watching: browser 2')")
    first.context.close()
    second.context.close()


def _flying_by_keyboard(browser, station, line, *, fake_clock=False):
    """A pilot's page on the keyboard, the robot unlocked and the relay armed."""
    page = open_page(browser, station, pad=False, fake_clock=fake_clock)
    take_control(page)
    choose_device(page, "keyboard")
    page.click("#unlock")
    line.wait_for("#start!")
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.relay.status.startsWith('armed')"
    )
    return page


def test_keyboard_flying_with_shift_as_the_dead_man(browser, station, line):
    page = _flying_by_keyboard(browser, station, line)
    page.wait_for_function("window.rovlinkStation.station.telemetry.commanded.lock === 'unlocked'")
    mark = line.mark()
    page.keyboard.down("d")  # no dead-man: nothing
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.power_percent === 40")
    page.keyboard.down("Shift")
    line.wait_for("#th.90.40!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#th.90.40!"]
    mark = line.mark()
    page.keyboard.up("Shift")
    line.wait_for("#th.90.0!", after=mark)
    page.keyboard.up("d")
    page.context.close()


def test_the_keys_on_a_page_flying_a_pad_say_why_they_fly_nothing(browser, station, line):
    page = piloting_by_pad(browser, station, line)  # (the one standard pad: in use)
    mark = line.mark()
    page.keyboard.down("Shift")
    page.keyboard.press("d")
    # Before, nothing moved and nothing said why.
    page.wait_for_selector("#toast:has-text('the keyboard flies nothing: the input device is')")
    assert "Fake Xbox pad" in page.text_content("#toast")
    page.keyboard.up("Shift")
    page.click("#unlock")  # a fence
    line.wait_for("#start!", after=mark)
    assert not [f for f in line.frames(mark) if f.startswith("#th.") and not f.endswith(".0!")]
    page.context.close()


@pytest.mark.realtime
def test_leaving_the_window_with_keys_held_zeroes_the_thrust(browser, station, line):
    page = _flying_by_keyboard(browser, station, line)
    mark = line.mark()
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    # The window loses the keyboard's focus (another window clicked): the keys' releases go
    # there, never to this page.
    left_s = time.monotonic()
    page.evaluate("dispatchEvent(new FocusEvent('blur'))")
    zero = line.wait_for("#th.90.0!", after=mark)
    assert zero.at_s - left_s < CUT_WITHIN_S
    page.keyboard.down("d")  # back, D repeating as still held, Shift not: nothing flies
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.power_percent === 40")
    page.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    assert line.frames(mark, commands_only=True)[-1] == "#h-!"
    assert line.frames(mark, commands_only=True).count("#th.90.40!") <= 2  # (one renewal)
    page.context.close()


# The keyboard's confirmation windows, shortened for the tests (the system's repeat of a key
# held is played by the page's own timer here: Playwright holds a key without repeating it).
SHORT_CONFIRMATION = """() => Object.assign(window.rovlinkStation.devices.keyboard,
  {pressConfirmMs: 500, repeatConfirmMs: 300})"""
# A key event as the system gives one (``{code, repeat, shiftKey}``).
KEY_EVENT = """([kind, init]) => document.body.dispatchEvent(
  new KeyboardEvent(kind, {bubbles: true, key: init.code.slice(-1).toLowerCase(), ...init}))"""
REPEATING = """(code) => { window.repeating = setInterval(() => document.body.dispatchEvent(
  new KeyboardEvent('keydown', {bubbles: true, code, repeat: true, shiftKey: true})), 30); }"""


@pytest.mark.realtime
def test_a_key_up_the_page_never_gets_zeroes_the_thrust(browser, station, line):
    # The system keeps a key-up for itself (macOS gives none for a key let go while Cmd is
    # down): before, the robot flew on that key for good.
    page = _flying_by_keyboard(browser, station, line, fake_clock=True)
    page.evaluate(SHORT_CONFIRMATION)
    mark = line.mark()
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    page.evaluate(REPEATING, "KeyD")  # held: the system repeats D, the key pressed last
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.deadman", timeout=2000)
    page.clock.run_for(800)  # past both windows: the repeats keep Shift and D held
    assert page.evaluate("window.rovlinkStation.devices.lastInput.power_percent") == 40
    page.evaluate("clearInterval(window.repeating)")  # D let go; its key-up never comes
    lost_s = time.monotonic()
    zero = line.wait_for("#th.90.0!", after=mark, timeout_s=3.0)
    assert zero.at_s - lost_s < 0.3 + CUT_WITHIN_S
    # The zero sent is that one: none went while the repeats held the keys.
    assert zero.at_s > lost_s
    assert line.frames(mark).count("#th.90.0!") == 1
    page.wait_for_selector("#device-status.warn:has-text('taken as released: press it again')")
    # Every key let go of (D's key-up still never came): nothing is left to press again, and
    # the badge says so (before, it asked for a press until the next one).
    page.keyboard.up("Shift")
    page.wait_for_selector("#device-status:text-is('input: keyboard')", timeout=1000)
    # Pressed again, it flies again.
    mark = line.mark()
    page.keyboard.up("d")
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    page.wait_for_selector("#device-status:text-is('input: keyboard')")
    page.context.close()


@pytest.mark.realtime
def test_keys_let_go_where_the_page_cannot_hear_them_fly_nothing(browser, station, line):
    page = _flying_by_keyboard(browser, station, line)
    mark = line.mark()
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    # Shift's key-up lost: the next key event says Shift is up. Before, it flew on on D.
    mark = line.mark()
    page.evaluate(KEY_EVENT, ["keydown", {"code": "KeyD", "repeat": True, "shiftKey": False}])
    line.wait_for("#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S * 2)
    page.keyboard.up("d")
    page.keyboard.up("Shift")
    # The browser's menu opened (a right click, or the menu key): the keys let go while it is
    # open have their key-ups go to it. Before, D and Shift stayed held.
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    mark = line.mark()
    page.mouse.click(700, 500, button="right")
    line.wait_for("#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S * 2)
    page.keyboard.up("d")
    page.keyboard.up("Shift")
    # The tab hidden with D and Shift held; D let go meanwhile (its key-up never came), and the
    # pilot back presses the dead-man again: before, the robot flew off on D.
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    mark = line.mark()
    page.evaluate(HIDE_THE_TAB, True)
    line.wait_for("#th.90.0!", after=mark, timeout_s=CUT_WITHIN_S * 2)
    page.evaluate(HIDE_THE_TAB, False)
    page.keyboard.up("Shift")
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.deadman === false")
    page.keyboard.down("Shift")
    page.wait_for_function("window.rovlinkStation.devices.lastInput?.deadman === true")
    page.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    assert "#th.90.40!" not in line.frames(mark)
    page.keyboard.up("Shift")
    page.context.close()


# The tab hidden (true) or shown again, as the browser tells the page.
HIDE_THE_TAB = """(hidden) => {
  Object.defineProperty(document, 'hidden', {configurable: true, get: () => hidden});
  document.dispatchEvent(new Event('visibilitychange')); }"""


@pytest.mark.realtime
def test_reloading_mid_dive_zeroes_the_thrust_and_comes_back_as_a_watcher(browser, station, line):
    page = flying_by_pad(browser, station, line, [0, -1, 0, 0], "#th.0.100!")
    mark = line.mark()
    reloaded_s = time.monotonic()
    page.reload()
    zero = line.wait_for("#th.0.0!", after=mark)
    assert zero.at_s - reloaded_s < CUT_WITHIN_S
    page.wait_for_function("window.rovlinkStation && window.rovlinkStation.station.id === 'p2'")
    page.evaluate("fakePads.connect(); fakePads.set(0, {axes: [0, -1, 0, 0], buttons: {4: true}})")
    page.wait_for_selector("#control-status:text-is('watching: nobody has control')")
    page.click("#stop")  # a fence: the held pad flew nothing
    line.wait_for("#stop!", after=mark)
    assert "#th.0.100!" not in line.frames(mark)
    page.context.close()


ARROWS_SCROLLED = """() => { window.arrowsScrolled = [];
  addEventListener('keydown', (event) => {
    if (event.code.startsWith('Arrow')) window.arrowsScrolled.push(!event.defaultPrevented);
  }); }"""


def test_flying_with_the_arrow_keys_does_not_scroll_the_page(browser, station, line):
    page = _flying_by_keyboard(browser, station, line)
    page.evaluate(ARROWS_SCROLLED)  # whether the browser's scrolling is left to each key
    mark = line.mark()
    page.keyboard.down("ArrowDown")  # (before, the instruments scrolled away as it flew)
    page.keyboard.down("Shift")
    page.keyboard.down("ArrowDown")  # (a repeat, as a key held down gives)
    line.wait_for("#th.180.40!", after=mark)
    page.keyboard.up("ArrowDown")
    page.keyboard.up("Shift")
    line.wait_for("#th.180.0!", after=mark)
    assert page.evaluate("window.arrowsScrolled") == [False, False]
    # A page that does not fly by keyboard (here: by pad) leaves the arrows to the browser.
    choose_device(page, "auto")
    page.keyboard.press("ArrowDown")
    assert page.evaluate("window.arrowsScrolled") == [False, False, True]
    page.context.close()


def test_no_silent_pick_of_the_input_device(browser, station, line):
    page = open_page(browser, station, pad=False)
    take_control(page)
    # The pilot is told under the top bar what keeps the robot still: no device, not "release
    # the dead-man to arm" (there was none to release).
    page.wait_for_selector("#flight-status:has-text('no gamepad: connect one')", timeout=2000)
    page.evaluate("fakePads.connect('USB headset buttons', '')")
    page.wait_for_selector("#device-status:has-text('no gamepad with the standard mapping')")
    page.wait_for_selector("#flight-status:has-text('no gamepad with the standard mapping')")
    page.evaluate("fakePads.connect('Pad A (STANDARD GAMEPAD)')")
    page.wait_for_selector("#device-status:has-text('Pad A')")
    page.click("#unlock")  # (the station locked the robot as it started)
    page.wait_for_function("!document.getElementById('flight-status').textContent")  # armed
    page.evaluate("fakePads.connect('Pad B (STANDARD GAMEPAD)')")
    page.wait_for_selector("#device-status:has-text('several gamepads: choose one')")
    choose_device(page, "pad:Pad B (STANDARD GAMEPAD)")
    page.wait_for_selector("#device-status:has-text('Pad B')")
    page.reload()  # the choice is kept
    page.wait_for_function("window.rovlinkStation && window.rovlinkStation.station.id !== null")
    page.evaluate("fakePads.connect('Pad A (STANDARD GAMEPAD)')")
    page.wait_for_selector("#device-status:has-text('not connected')")
    page.context.close()


def test_settings_send_values_within_the_command_table(browser, station, line):
    page = open_page(browser, station, pad=False)
    take_control(page)
    page.click("#settings-panel summary")
    assert page.get_attribute("#setting-mgmp", "max") == "255"
    page.evaluate(COMMANDS_SENT)
    mark = line.mark()
    page.fill("#setting-mgmp", "200")
    page.press("#setting-mgmp", "Enter")
    line.wait_for("#mgmp.200!", after=mark)
    # Stamped with the page's clock: the station does not send one held up on a slow network.
    assert page.evaluate("window.commandsSent.map(m => typeof m.sent_ms)") == ["number"]
    page.fill("#setting-mvpdp", "120")  # beyond 0–99: the browser refuses to submit it
    page.press("#setting-mvpdp", "Enter")
    page.fill("#target-depth", "150")
    page.press("#target-depth", "Enter")
    line.wait_for("#mvd.150!", after=mark)
    assert not [frame for frame in line.frames(mark) if frame.startswith("#mvpdp")]
    page.context.close()


def test_the_record_button_records_and_the_page_downloads(browser, line, tmp_path):
    from rovlink.recorder import FrameEntry, read_entries

    with running_station(line.url, "--recordings", str(tmp_path)) as served:
        page = open_page(browser, served, pad=False)
        assert page.is_disabled("#record")  # a watcher cannot record
        take_control(page)
        page.click("#record")
        page.wait_for_selector("#recording.active")
        assert page.text_content("#record") == "■ Stop recording"
        # Every page sees who started it (docs/station.md); before, only the file and time.
        page.wait_for_selector("#recording-status:has-text('by browser 1')")
        mark = line.mark()
        page.click("#unlock")
        line.wait_for("#start!", after=mark)
        page.click("#record")
        page.wait_for_selector("#recording:not(.active)")
        page.click("#recordings summary")
        assert page.evaluate(STOP_REACHABLE)  # (before, the open list lay over it)
        with page.expect_download() as download_info:
            page.click("#recordings-list a")
        downloaded = tmp_path / "from-the-page.mcap"
        download_info.value.save_as(downloaded)
        page.context.close()
    sent = [
        entry.name
        for entry in read_entries(str(downloaded))
        if isinstance(entry, FrameEntry) and entry.direction == "out"
    ]
    assert "start" in sent


def test_a_locked_robot_never_shows_flying(browser, station, line):
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    mark = line.mark()
    page.click("#stop")
    line.wait_for("#stop!", after=mark)
    set_pad(page, axes=[1, 0, 0, 0], deadman=False)  # released and held again: armed, locked
    page.wait_for_function(
        "window.rovlinkStation.station.telemetry.relay.status.startsWith('motors locked')"
    )
    set_pad(page, axes=[1, 0, 0, 0], deadman=True)
    # The station armed on that dead-man: the row shown is the one drawn from the same message
    # (before, it read "flying" in green beside "motors: locked").
    page.wait_for_function("window.rovlinkStation.station.telemetry.relay.armed === true")
    assert page.text_content("#relay-state") == "motors locked: unlock (#start!) to fly"
    assert page.get_attribute("#relay-state", "class") != "flying"
    assert "unlock (#start!)" in page.text_content("#flight-status")
    # (After the #stop!: a renewal of the flight may have gone between the mark and the click.)
    frames = line.frames(mark)
    after_stop = frames[frames.index("#stop!") + 1 :]
    assert not [frame for frame in after_stop if frame.startswith("#th.90.1")]
    page.context.close()


def test_stop_with_the_dead_man_released_takes_one_press_to_fly_again(browser, station, line):
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    mark = line.mark()
    set_pad(page, axes=[0, 0, 0, 0], deadman=False)
    line.wait_for("#th.90.0!", after=mark)
    page.click("#stop")
    line.wait_for("#stop!", after=mark)
    # The dead-man is released already: the page says so again after the cut, and the banner
    # names what keeps the robot still (the lock), not "release the dead-man", which the pilot
    # had done. Before, the dead-man had to be pressed, released and pressed again.
    page.wait_for_selector(
        "#flight-status:text-is('motors locked: unlock (#start!) to fly')", timeout=2000
    )
    unlock_and_arm(page, line)
    mark = line.mark()
    set_pad(page, axes=[1, 0, 0, 0], deadman=True)
    line.wait_for("#th.90.100!", after=mark, timeout_s=1.0)
    page.context.close()


def test_a_silent_station_is_shown_as_such_not_as_live(browser, station, line):
    page = open_page(browser, station, pad=False)
    page.wait_for_selector("#stale-banner", state="hidden")
    os.kill(station.process.pid, signal.SIGSTOP)  # a network that went quiet, seen from here
    try:
        page.wait_for_selector("#stale-banner:has-text('no word from the station')", timeout=5000)
        assert page.evaluate("document.body.classList.contains('stale')")
        assert page.text_content("#connection") == "station silent"
    finally:
        os.kill(station.process.pid, signal.SIGCONT)
    page.wait_for_selector("#stale-banner", state="hidden")
    assert not page.evaluate("document.body.classList.contains('stale')")
    page.context.close()


# The texts drawn on the heading tape from now on, in window.headingTexts.
HEADING_TEXTS = """() => { const fill = CanvasRenderingContext2D.prototype.fillText;
  window.headingTexts = [];
  CanvasRenderingContext2D.prototype.fillText = function (text, ...rest) {
    if (this.canvas.id === 'heading') window.headingTexts.push(String(text));
    return fill.call(this, text, ...rest); }; }"""


def test_readings_that_stop_are_shown_as_missing(browser, station, line):
    page = open_page(browser, station, pad=False)
    page.wait_for_function("window.rovlinkStation.charts.columns[1].length > 3")
    line.close()  # the robot's end goes away: polls fail, the last reading is not current
    page.wait_for_selector("#stale-banner:has-text('no reading from the robot')", timeout=10_000)
    page.wait_for_selector("#depth-value:text-is('–')")  # once a poll has failed
    # The last poll's round trip: there was none. Before, the last one answered was shown as
    # the link's now ("0.4 ms (avg 0.7)").
    round_trip = page.locator("#link-health tr:has(td:text-is('round trip')) td").nth(1)
    assert round_trip.text_content().startswith("none now; last answered: ")
    assert "bad" in (round_trip.get_attribute("class") or "")
    # A gap in the charts, not a line drawn across it.
    page.wait_for_function("window.rovlinkStation.charts.columns[1].includes(null)")
    # The heading tape says there is no reading, as the attitude does; before, it showed its
    # scale round north, as if the robot pointed there.
    page.evaluate(HEADING_TEXTS)
    page.wait_for_function("window.headingTexts.length > 0")
    texts = page.evaluate("window.headingTexts")
    assert "no reading" in texts
    assert "N" not in texts
    page.context.close()


@pytest.mark.slow  # (the lateness builds up in real time, to over a second: some 6 s)
def test_readings_that_arrive_late_are_shown_as_old(browser, station, line):
    page = open_page(browser, station, pad=False)
    page.wait_for_function("window.rovlinkStation.station.telemetryCount > 3")
    session = page.context.new_cdp_session(page)
    session.send("Network.enable")
    # A network slower than the readings: they all arrive, each later than the one before.
    # (Before, the page showed them as live, seconds old, between bursts.)
    slow = {"offline": False, "latency": 0, "downloadThroughput": 300, "uploadThroughput": -1}
    session.send("Network.emulateNetworkConditions", slow)
    page.wait_for_selector("#stale-banner:has-text('arrive')", timeout=10_000)
    assert "late (a slow network?): everything shown is old" in page.text_content("#stale-banner")
    assert page.evaluate("document.body.classList.contains('stale')")
    session.send("Network.emulateNetworkConditions", {**slow, "downloadThroughput": -1})
    page.wait_for_selector("#stale-banner", state="hidden", timeout=8000)  # caught up
    page.context.close()


def test_stop_on_the_pad_of_a_page_that_lost_control_still_stops(browser, station, line):
    first = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    second = open_page(browser, station, pad=False)
    take_control_from_another(second)
    first.wait_for_selector("#flight-status:has-text('you are no longer the pilot')")
    mark = line.mark()
    set_pad(first, stop_button=True)  # (before, a pad's STOP did nothing once control was lost)
    line.wait_for("#stop!", after=mark)
    set_pad(first, stop_button=False)
    # A pad first seen with STOP held (the press that shows a pad to a page) sends nothing.
    second.evaluate("fakePads.connect(); fakePads.set(0, {buttons: {1: true}})")
    second.wait_for_function("window.rovlinkStation.devices.buttonsOf?.index === 0")
    second.wait_for_function("window.rovlinkStation.devices.previousButtons.stop === true")
    mark = line.mark()
    second.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#h-!"]
    first.context.close()
    second.context.close()


# The page has read this many pads besides the one in use (a page without the rule reads none:
# it does not wait, and the press is then missed as it always was).
OTHER_STOPS_SEEN = "n => (window.rovlinkStation.devices.otherStops?.size ?? n) === n"


def press_on(page: Page, index: int, buttons: dict[int, bool], axes: list[float] | None = None):
    """Set the buttons (by number) and axes of the fake pad in slot ``index``."""
    page.evaluate(
        "([index, buttons, axes]) => fakePads.set(index, {buttons, axes})",
        [index, {str(number): down for number, down in buttons.items()}, axes],
    )


def test_every_pad_in_reach_stops_and_only_the_chosen_one_flies(browser, station, line):
    page = open_page(browser, station)
    choose_device(page, "pad:Fake Xbox pad (STANDARD GAMEPAD)")
    take_control(page)
    unlock_and_arm(page, line)
    mark = line.mark()
    set_pad(page, axes=[1, 0, 0, 0], deadman=True)
    line.wait_for("#th.90.100!", after=mark)
    # A co-pilot's pad of another kind (standard mapping: B is STOP) and a headset.
    page.evaluate("fakePads.connect('Co-pilot pad (STANDARD GAMEPAD)')")
    page.evaluate("fakePads.connect('USB headset buttons', '')")
    page.wait_for_function(OTHER_STOPS_SEEN, arg=1)  # (the headset is not read)
    mark = line.mark()
    # Everything but STOP on the co-pilot's pad moves nothing: its dead-man, stick, unlock.
    press_on(page, 1, {DEADMAN: True, UNLOCK: True, CLAW_OPEN: True}, axes=[0, 1, 0, -1])
    press_on(page, 2, {STOP_BUTTON: True})  # the headset's button 1 is no STOP
    press_on(page, 1, {STOP_BUTTON: True})  # (before, it did nothing: the pad was not read)
    line.wait_for("#stop!", after=mark)
    page.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    # Only the pilot's own pad flying on (its renewal) and the STOP with its cut: nothing from
    # the co-pilot's other buttons and sticks (no #start!, #h+!, #th.0.…, #mvd).
    flown = {"#th.90.100!", "#stop!", "#th.90.0!", "#mvs.+0!", "#h-!"}
    assert set(line.frames(mark, commands_only=True)) <= flown
    # The page says what each pad does.
    pads = page.text_content("#pad-list") or ""
    assert "Co-pilot pad (STANDARD GAMEPAD) (standard mapping) · its STOP (button 1)" in pads
    assert "USB headset buttons (non-standard mapping) · not read" in pads
    press_on(page, 1, {STOP_BUTTON: False})
    press_on(page, 2, {STOP_BUTTON: False})
    # A spare of the chosen pad's kind uses the pilot's mapping: STOP moved to button 7.
    page.fill("[data-button='stop']", "7")
    page.press("[data-button='stop']", "Enter")
    page.evaluate("fakePads.connect('Fake Xbox pad (STANDARD GAMEPAD)')")
    page.wait_for_function(OTHER_STOPS_SEEN, arg=2)
    page.wait_for_selector("#pad-list:has-text('its STOP (button 7)')", state="attached")
    mark = line.mark()
    press_on(page, 3, {STOP_BUTTON: True})  # its B is not its STOP any more
    press_on(page, 3, {7: True})
    line.wait_for("#stop!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#stop!"]
    # A pad first seen with STOP held (the press that shows it to the page) sends nothing.
    page.evaluate("fakePads.disconnect(1)")
    page.wait_for_function(OTHER_STOPS_SEEN, arg=1)
    page.evaluate(  # (in one script: the page cannot poll in between)
        "fakePads.set(fakePads.connect('Second co-pilot pad (STANDARD GAMEPAD)'),"
        " {buttons: {1: true}})"
    )
    page.wait_for_function(OTHER_STOPS_SEEN, arg=2)
    mark = line.mark()
    page.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#h-!"]
    page.context.close()


PAD_STOPS = "JSON.parse(localStorage.getItem('rovlink.pad-stops') || '{}')"


def test_a_spare_pad_without_the_standard_mapping_stops_once_its_stop_is_learnt(
    browser, station, line
):
    # A spare pad of another kind without the standard mapping (a generic USB pad) was never
    # read: which of its buttons is STOP was not known, and nothing could tell the page.
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    page.evaluate("fakePads.connect('Generic USB pad', '')")
    learn = "#pad-list button[data-learn-stop='1']"
    page.wait_for_selector(learn)
    pads = page.text_content("#pad-list") or ""
    assert "Generic USB pad (non-standard mapping) · not read" in pads
    press_on(page, 1, {5: True})  # held as learning starts: not what is learnt
    page.click(learn)
    page.wait_for_selector("#pad-list button:text('press its STOP…')")
    mark = line.mark()
    press_on(page, 1, {9: True})  # its STOP, pressed to be learnt: no stop for that press
    page.wait_for_function(f"{PAD_STOPS}['Generic USB pad'] === 9")
    page.wait_for_selector("#pad-list:has-text('its STOP (button 9) stops the robot')")
    page.wait_for_function(OTHER_STOPS_SEEN, arg=1)  # read from now on, its STOP held
    page.click("#claw-close")  # a fence
    line.wait_for("#h-!", after=mark)
    assert "#stop!" not in line.frames(mark, commands_only=True)
    # Its other buttons and sticks move nothing; its STOP, pressed again, stops.
    press_on(page, 1, {5: False, 9: False, DEADMAN: True, UNLOCK: True}, axes=[0, 1, 0, -1])
    page.wait_for_function(
        "window.rovlinkStation.devices.otherStops.get('1:Generic USB pad') === false"
    )
    mark = line.mark()
    press_on(page, 1, {9: True})
    line.wait_for("#stop!", after=mark)
    sent = line.frames(mark, commands_only=True)
    # (the first pad, still flying, may renew its thrust before the stop: nothing else)
    assert set(sent[: sent.index("#stop!")]) <= {"#th.90.100!"}, sent
    # Kept in the browser: a page opened later reads it at once.
    later = open_page(browser, station, pad=False)
    later.evaluate(
        "localStorage.setItem('rovlink.pad-stops', JSON.stringify({'Generic USB pad': 9}))"
    )
    later.reload()
    later.wait_for_function("window.rovlinkStation && window.rovlinkStation.station.id !== null")
    later.evaluate("fakePads.connect('Generic USB pad', '')")
    later.wait_for_function(OTHER_STOPS_SEEN, arg=1)
    mark = line.mark()
    press_on(later, 0, {9: True})
    line.wait_for("#stop!", after=mark)
    later.context.close()
    page.context.close()


def test_keys_typed_in_a_field_do_not_fly(browser, station, line):
    page = _flying_by_keyboard(browser, station, line, fake_clock=True)
    page.fill("#target-depth", "150")
    page.wait_for_selector("#device-status.warn:has-text('paused while typing')")
    mark = line.mark()
    page.keyboard.down("Shift")  # Shift with the arrows selects text in the field
    page.keyboard.press("ArrowLeft")
    page.keyboard.down("ArrowLeft")
    page.clock.run_for(300)  # held: every timer of the page's input loop fires meanwhile
    page.keyboard.up("ArrowLeft")
    page.keyboard.up("Shift")
    page.press("#target-depth", "Enter")  # a fence
    line.wait_for("#mvd.150!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#mvd.150!"]  # (before: #th.270.40!)
    page.click(".log h2")  # out of the field: the keys fly again
    page.wait_for_selector("#device-status:text-is('input: keyboard')")
    page.keyboard.down("Shift")
    page.keyboard.down("d")
    line.wait_for("#th.90.40!", after=mark)
    page.keyboard.up("d")
    page.keyboard.up("Shift")
    page.context.close()


def test_a_page_that_hears_nothing_for_10_s_reconnects(browser, station, line):
    page = open_page(browser, station, pad=False, fake_clock=True)
    take_control(page)
    os.kill(station.process.pid, signal.SIGSTOP)
    try:
        # Past the page's 10 s, every one of its timers firing on the way (a jump of the clock
        # would be taken for a tab put to sleep): it gives the silent socket up.
        page.clock.run_for(11_000)
    finally:
        os.kill(station.process.pid, signal.SIGCONT)
    page.wait_for_function("window.rovlinkStation.station.id === 'p2'")
    page.wait_for_selector("#stale-banner", state="hidden")
    assert "no longer the pilot" in page.text_content("#flight-status")
    page.context.close()


def test_learning_a_button_fires_nothing(browser, station, line):
    # A watcher setting up its pad while another flies.
    page = open_page(browser, station, fake_clock=True)
    page.wait_for_function("window.rovlinkStation.devices.buttonsOf !== null")
    mark = line.mark()
    page.click("[data-learn='claw_open']")
    set_pad(page, stop_button=True)  # B, STOP by default: learnt as claw open, no STOP
    page.wait_for_function(
        "JSON.parse(localStorage.getItem('rovlink.mapping') || '{}').buttons?.claw_open === 1"
    )
    page.clock.run_for(100)  # held: the page reads the pad on every frame meanwhile
    set_pad(page, stop_button=False)
    page.click("#stop")  # a fence
    line.wait_for("#stop!", after=mark)
    assert line.frames(mark, commands_only=True) == ["#stop!"]
    page.click("#mapping-editor button:text('default mapping')")
    # A number the pad cannot have is refused, named, and the button kept: before, STOP was
    # mapped to button 40 (or, left empty, to 0: unlock) and B stopped nothing.
    for typed in ("40", "1.5", ""):
        page.fill("[data-button='stop']", typed)
        page.press("[data-button='stop']", "Enter")
        mark = line.mark()
        set_pad(page, stop_button=True)
        line.wait_for("#stop!", after=mark)
        set_pad(page, stop_button=False)
        page.wait_for_selector("#toast:has-text('STOP (#stop!): a button number 0–31')")
        assert page.input_value("[data-button='stop']") == "1"
    page.context.close()


def test_a_stop_from_another_line_shows_on_every_page_with_hear_other_lines(browser):
    # Before, every page went on showing "unlocked" after another tool's #stop!.
    line = ControllerLine(pty=True)
    assert line.pty_path is not None
    try:
        with running_station(line.url, "--hear-other-lines") as served:
            line.wait_for("#debug1!")  # the station put debug output on
            pilot = piloting_by_pad(browser, served, line)  # (unlocked)
            watcher = open_page(browser, served, pad=False)
            with rovlink.connect(line.pty_path, timeout=1.0, keepalive=None) as bystander:
                bystander.stop()
            for page in (pilot, watcher):
                page.wait_for_function(
                    "document.getElementById('lock-state').textContent"
                    " === 'locked (stopped by another line)'"
                )
                assert page.get_attribute("#lock-state", "class") == "locked"
            pilot.context.close()
            watcher.context.close()
    finally:
        line.close()


def test_a_watchers_relay_row_says_unlocked_after_another_line_unlocks_with_hear_other_lines(
    browser,
):
    # Before, after another line's #stop! then #start!, the watcher's relay row went by the lock
    # as the station sent it and said "motors locked" under "unlocked (started by another line)".
    line = ControllerLine(pty=True)
    assert line.pty_path is not None
    try:
        with running_station(line.url, "--hear-other-lines") as served:
            line.wait_for("#debug1!")
            watcher = open_page(browser, served, pad=False)
            with rovlink.connect(line.pty_path, timeout=1.0, keepalive=None) as bystander:
                bystander.start()  # (the station locked the robot as it started)
                watcher.wait_for_selector(
                    "#lock-state:text-is('unlocked (started by another line)')"
                )
                bystander.stop()
                watcher.wait_for_selector("#lock-state:text-is('locked (stopped by another line)')")
                bystander.start()
                watcher.wait_for_selector(
                    "#lock-state:text-is('unlocked (started by another line)')"
                )
                watcher.wait_for_selector(
                    "#relay-state:text-is('motors unlocked (started by another line);"
                    " nobody has control')",
                    timeout=2000,
                )
                bystander.stop()
            watcher.context.close()
    finally:
        line.close()


@pytest.mark.realtime
def test_a_controller_that_stops_answering_is_stopped_and_the_pilot_sees_why(
    browser, station, line
):
    # Its TX wire broke: it hears and obeys, answers nothing. Before, the pad kept flying it
    # while the page showed old depth, leak and attitude.
    page = flying_by_pad(browser, station, line, [1, 0, 0, 0], "#th.90.100!")
    mark = line.mark()
    silent_at_s = time.monotonic()
    line.stop_replying()
    stop = line.wait_for("#stop!", after=mark, timeout_s=5.0)
    assert stop.at_s - silent_at_s < TELEMETRY_LOST_S + CUT_WITHIN_S
    page.wait_for_selector("#flight-status:has-text('the controller stopped answering')")
    page.wait_for_selector("#stale-banner:has-text('no reading from the robot')")
    page.wait_for_selector("text=depth, leak and attitude are not known")  # the event log
    assert line.controller_locked  # every output to zero
    after = line.frames(mark, commands_only=True)
    assert not [f for f in after[after.index("#stop!") :] if f.startswith(("#th.", "#mvs."))]
    page.context.close()
