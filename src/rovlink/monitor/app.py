"""The textual dashboard: live sensors, the state as last sent, link health, a depth chart.

All link I/O runs in one worker: it connects, then polls ``#qsa!`` at the chosen rate through
the asyncio client, never in a key handler's way. Keys send their frames at once (the driver
writes without waiting for anything queued), so ``space`` stops the robot even while a poll is
waiting out its timeout on a silent link; a slow link shows up as link-health figures, not as a
frozen screen.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import time
from collections.abc import Awaitable, Callable
from typing import ClassVar, Literal

from rich.console import RenderableType
from rich.text import Text
from textual import events
from textual.app import App, ComposeResult
from textual.binding import Binding, BindingType
from textual.containers import Container, Vertical
from textual.css.query import NoMatches
from textual.widget import Widget
from textual.widgets import Digits, Footer, Header, Static

from rovlink.aio import AsyncClient
from rovlink.client import ClientError, ConnectionLostError, QueryTimeoutError
from rovlink.client.events import ClientEvent, LinkState
from rovlink.client.options import StrayCallback
from rovlink.logs import WarningsShownBy
from rovlink.monitor import controls
from rovlink.monitor.chart import SAMPLE_MARK, TARGET_MARK, depth_chart
from rovlink.monitor.panels import (
    attitude_text,
    commanded_text,
    controller_message_text,
    depth_text,
    leak_text,
    link_text,
    small_screen_text,
    stale_text,
)
from rovlink.monitor.readings import DEFAULT_WINDOW_S, Readings
from rovlink.piloting import LockState, SentFrame, TrackedClient
from rovlink.piloting.no_suspend import suspension_refused
from rovlink.piloting.tracked import REOPENED_NOTICE, STOP_KEPT_NOTICE, STOP_UNSENT_NOTICE
from rovlink.protocol import BadFrame, Command, Event
from rovlink.protocol import Text as DebugText
from rovlink.protocol.announcements import Announcement
from rovlink.protocol.visible import visible

__all__ = ["Connector", "MonitorApp", "Panel", "ShownIfRoom"]

#: Opens the connection, given the callback for what the controller sends unasked.
Connector = Callable[[StrayCallback], Awaitable[AsyncClient]]

#: How often the panels are redrawn between readings (silence grows, link figures change).
_REDRAW_S = 0.25
#: How long leaving may wait for ``#stop!`` to be written (it is not acknowledged).
_STOP_WRITE_TIMEOUT_S = 1.0
#: Below this many columns, the top boxes go in two rows of two and the footer is compact.
NARROW_BELOW_COLUMNS = 100
#: The smallest terminal the boxes fit in, narrow (two rows of two) and wide (three in a row):
#: below it, the screen would scroll and cut boxes and keys off, so the essentials are shown
#: one per line instead (see ``small_screen_text``).
NARROW_MIN_SIZE = (80, 24)
WIDE_MIN_SIZE = (NARROW_BELOW_COLUMNS, 19)
#: Rows the chart's box needs to draw something: its border, two rows of plot, the axis and the
#: time labels.
_CHART_MIN_ROWS = 6
#: What SIGTSTP (a Ctrl-Z where the terminal's signal keys are on, ``kill -TSTP``) does.
NO_SUSPEND_TEXT = (
    "SIGTSTP does not suspend the monitor (the robot would go on unattended): space stops it,"
    " q quits"
)
#: The boxes that show a sensor reading: each is marked when the reading is stale.
_READING_BOXES = ("#depth-box", "#attitude", "#leak")


class Panel(Widget):
    """A bordered box whose content is drawn for its current size by ``draw(width, height)``."""

    def __init__(
        self,
        draw: Callable[[int, int], RenderableType],
        *,
        title: str = "",
        id: str | None = None,
        classes: str | None = None,
    ) -> None:
        super().__init__(id=id, classes=classes)
        self._draw = draw
        self._drawn: RenderableType | None = None
        self.border_title = title

    def render(self) -> RenderableType:
        """The content for the size the layout gave this panel."""
        self._drawn = self._draw(self.content_size.width, self.content_size.height)
        return self._drawn

    def refresh_if_changed(self) -> None:
        """Draw the panel again if its content changed: each redraw writes the whole box to the
        terminal, many times a second, which an idle dashboard has no need to."""
        if self._draw(self.content_size.width, self.content_size.height) != self._drawn:
            self.refresh()

    def text(self) -> str:
        """The content as plain text (what a person reads on screen)."""
        rendered = self.render()
        return rendered.plain if isinstance(rendered, Text) else str(rendered)


class ShownIfRoom(Vertical):
    """A container that shows its content only while it is at least ``min_height`` rows high.

    A bordered box is never less than its border: given no room, it would push the screen into
    scrolling. This container can shrink to nothing, and hides its content when too short to
    show it (it gets its own size after each layout, its content or not).
    """

    def __init__(self, *children: Widget, min_height: int, id: str | None = None) -> None:
        super().__init__(*children, id=id)
        self._min_height = min_height

    def on_resize(self, event: events.Resize) -> None:
        """Show the content if it fits."""
        for child in self.children:
            child.display = event.size.height >= self._min_height


class MonitorApp(App[None]):
    """``rovlink monitor``: connect with ``connect``, poll at ``rate_hz``, drive with keys."""

    TITLE = "rovlink monitor"
    ENABLE_COMMAND_PALETTE = False
    CSS = """
    Screen { layout: vertical; }
    Screen.leak Header { background: $error; color: $text; text-style: bold; }
    /* Depth, attitude and the state as last sent side by side, the leak banner under them. */
    #top {
        layout: grid; grid-size: 3 2; grid-columns: 30 32 1fr; grid-rows: 8 3; height: auto;
    }
    #top > * { width: 100%; height: 100%; }
    #leak { column-span: 3; }
    /* Narrower, there is no room for three boxes in a row ("motors unlocked (as last sent)"
       wrapped over three lines of the third): two rows of two, the state as last sent
       under the depth, in the wider column, and the leak beside it. */
    Screen.-narrow #top { grid-size: 2 2; grid-columns: 1fr 34; grid-rows: 8 8; }
    Screen.-narrow #leak { column-span: 1; }
    Panel, #depth-box { border: round $primary; border-title-align: left; padding: 0 1; }
    #depth-digits { width: auto; }
    #depth-readout { height: 3; }
    #leak { border: round $success; content-align: center middle; }
    /* A stale reading keeps its box, dimmed, with its age on the bottom border. */
    #depth-box.-stale, #attitude.-stale, #leak.-stale {
        border: round $warning; border-subtitle-color: $warning; border-subtitle-style: bold;
    }
    #depth-box.-stale #depth-digits { color: $text-muted; }
    #leak.alarm { background: $error; color: $text; border: heavy $warning; text-style: bold; }
    #link { height: 6; }
    /* The chart has what the link leaves (at 80×24, nothing: see ShownIfRoom). With no room
       left, 1fr is still one row: clipped here, not a screen that scrolls by one row. */
    #lower { height: 1fr; min-height: 6; overflow: hidden; }
    #chart-room { height: 1fr; min-height: 0; }
    #chart { height: 1fr; }
    /* Too small for the boxes: the essentials alone, one per line (the keys among them). */
    #small {
        display: none; height: 1fr; border: none; padding: 0;
        text-wrap: nowrap; text-overflow: ellipsis;
    }
    Screen.-small #small { display: block; }
    Screen.-small Header, Screen.-small #top, Screen.-small #lower, Screen.-small Footer {
        display: none;
    }
    """
    BINDINGS: ClassVar[list[BindingType]] = [
        Binding("space", "stop", "STOP", key_display="space", priority=True),
        Binding("s", "start", "start", priority=True),
        Binding(
            "left",
            f"turn(-{controls.DIRECTION_STEP_DEG})",
            "turn",
            key_display="←→",
            priority=True,
        ),
        Binding("right", f"turn({controls.DIRECTION_STEP_DEG})", "turn", show=False, priority=True),
        Binding(
            "up", f"power({controls.POWER_STEP_PERCENT})", "power", key_display="↑↓", priority=True
        ),
        Binding(
            "down", f"power(-{controls.POWER_STEP_PERCENT})", "power", show=False, priority=True
        ),
        Binding(
            "pagedown",
            f"depth({controls.DEPTH_STEP_CM})",
            "depth",
            key_display="PgUp/PgDn",
            priority=True,
        ),
        Binding("pageup", f"depth(-{controls.DEPTH_STEP_CM})", "depth", show=False, priority=True),
        Binding("o", "claw('h+')", "claw", key_display="o/c", priority=True),
        Binding("c", "claw('h-')", "claw", show=False, priority=True),
        Binding("r", "reset_leak", "reset leak", priority=True),
        Binding("q", "quit_safely", "quit", priority=True),
        # Each letter in capitals too: with caps lock on, q did nothing, nor did s.
        Binding("S", "start", "start", show=False, priority=True),
        Binding("O", "claw('h+')", "claw", show=False, priority=True),
        Binding("C", "claw('h-')", "claw", show=False, priority=True),
        Binding("R", "reset_leak", "reset leak", show=False, priority=True),
        Binding("Q", "quit_safely", "quit", show=False, priority=True),
        Binding("ctrl+q", "quit_safely", "quit", show=False, priority=True),
        Binding("ctrl+c", "quit_safely", "quit", show=False, priority=True),
    ]

    def __init__(
        self,
        connect: Connector,
        *,
        description: str = "",
        rate_hz: float = 5.0,
        algorithm: str = "crc8",
        window_s: float = DEFAULT_WINDOW_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``description`` names the robot in the title; ``rate_hz`` is the polling rate;
        ``clock`` (monotonic seconds) times the readings, so a test can make them old."""
        if isinstance(rate_hz, bool) or not isinstance(rate_hz, int | float) or rate_hz <= 0:
            raise ValueError(f"rate_hz must be a positive number, got {rate_hz!r}")
        super().__init__()
        self._connect = connect
        self._clock = clock
        self._stale = False
        self._algorithm = algorithm
        self.rate_hz = rate_hz
        self.readings = Readings(window_s=window_s)
        self.rov: TrackedClient | None = None
        self.sub_title = description
        self._link_state = "connecting…"
        self._last_message = ""
        self._last_message_at_s = 0.0  # (on the clock of the readings)
        #: Set when the monitor left, unlocked, with the link down: what to say of the
        #: ``#stop!`` that never went (the dashboard is gone by then: the command says it).
        self.stop_unsent: str | None = None
        self._depth_readout: Text | None = None
        # Written to stderr, the library's warnings would land over the dashboard's screen.
        self._warnings = WarningsShownBy(self._notify_warning)
        self._warnings_loop: asyncio.AbstractEventLoop | None = None
        self._no_suspend = contextlib.ExitStack()

    # -- layout ---------------------------------------------------------------------------------

    def compose(self) -> ComposeResult:
        """Depth, attitude and the state as last sent on top; leak, link and chart below."""
        yield Header()
        yield Panel(self._draw_small, id="small")
        with Container(id="top"):
            with Vertical(id="depth-box"):
                yield Digits("—", id="depth-digits")
                yield Static(id="depth-readout")
            yield Panel(self._draw_attitude, title="attitude", id="attitude")
            yield Panel(self._draw_commanded, title="commanded, as last sent", id="commanded")
            yield Panel(
                lambda width, height: leak_text(self.readings, stale=self._stale),
                title="leak",
                id="leak",
            )
        with Vertical(id="lower"):
            yield Panel(self._draw_link, title="link", id="link")
            with ShownIfRoom(min_height=_CHART_MIN_ROWS, id="chart-room"):
                yield Panel(self._draw_chart, title="depth over time", id="chart")
        yield Footer()

    def on_mount(self) -> None:
        """Start the link worker and the redraw timer; show the library's warnings as
        notifications while the dashboard owns the terminal."""
        self.query_one("#depth-box").border_title = "depth, cm"
        self._fit_size(self.size.width, self.size.height)
        self._warnings_loop = asyncio.get_running_loop()
        self._warnings.attach()
        # (Here, once textual's driver has put in its own SIGTSTP handler, which stops the
        # process: a stopped dashboard could not stop the robot.)
        self._no_suspend.enter_context(
            suspension_refused(lambda: self.notify(NO_SUSPEND_TEXT, severity="warning"))
        )
        self.run_worker(self._link_loop(), name="link", group="link", exclusive=True)
        self.set_interval(_REDRAW_S, self._redraw)

    def on_resize(self, event: events.Resize) -> None:
        """Lay the boxes out for the terminal's new size."""
        self._fit_size(event.size.width, event.size.height)

    async def on_event(self, event: events.Event) -> None:
        """Only keys drive the robot: the terminal's mouse events are dropped here, before
        textual hands them on. A footer key acts on a mere press of the button, so the click
        that focuses the terminal's window, landing on ``s start`` or ``↑↓ power``, would
        unlock the motors or add thrust."""
        if isinstance(event, events.MouseEvent) and not event.is_forwarded:
            return
        await super().on_event(event)

    @property
    def needed_size(self) -> tuple[int, int]:
        """The smallest terminal the boxes fit in at the present width."""
        return WIDE_MIN_SIZE if self.size.width >= NARROW_BELOW_COLUMNS else NARROW_MIN_SIZE

    def _fit_size(self, width: int, height: int) -> None:
        narrow = width < NARROW_BELOW_COLUMNS
        self.screen.set_class(narrow, "-narrow")
        needed_width, needed_height = WIDE_MIN_SIZE if not narrow else NARROW_MIN_SIZE
        self.screen.set_class(width < needed_width or height < needed_height, "-small")
        with contextlib.suppress(NoMatches):
            # Compact, the keys fit in 80 columns, "q quit" last among them.
            self.query_one(Footer).compact = narrow

    def on_unmount(self) -> None:
        """Warnings go where they went before (stderr) once the dashboard is gone."""
        self._warnings.detach()
        self._no_suspend.close()

    def _notify_warning(self, message: str, level: int) -> None:
        severity: Literal["warning", "error"] = "error" if level >= logging.ERROR else "warning"
        show = functools.partial(self.notify, visible(message), severity=severity)
        loop = self._warnings_loop
        try:
            on_loop = asyncio.get_running_loop() is loop
        except RuntimeError:  # no loop on this thread
            on_loop = False
        if on_loop or loop is None:
            show()
        else:
            # Queued, never waited for: the thread that logs (the client's reader, the
            # simulated controller of sim://) may hold what the event loop is waiting for.
            loop.call_soon_threadsafe(show)

    # -- the link -------------------------------------------------------------------------------

    @property
    def period_s(self) -> float:
        """Seconds between polls."""
        return 1.0 / self.rate_hz

    async def _link_loop(self) -> None:
        try:
            client = await self._connect(self._on_event)
        except (ConnectionError, ValueError, OSError) as error:
            self._link_state = f"could not connect: {error}"
            self._redraw()
            return
        rov = TrackedClient(client, algorithm=self._algorithm)
        rov.add_sent_listener(self._on_sent)
        rov.add_heard_listener(self._on_heard)
        client.subscribe(self._on_client_event)
        self.rov = rov
        self._link_state = client.description
        loop = asyncio.get_running_loop()
        try:
            # Until a poll says the link is gone and why (a closed client raises at once).
            while True:
                started_s = loop.time()
                try:
                    reading = await rov.sensors()
                except QueryTimeoutError:
                    pass  # counted in rov.health, shown on the link panel
                except ConnectionLostError as error:
                    if client.closed:
                        self._link_state = f"lost: {error}"
                        break
                    # Being reopened (the link panel says so): the polls go on, and fail at
                    # once until it is.
                else:
                    self._link_state = client.description
                    self.readings.record(reading, self._clock())
                self._redraw()
                await asyncio.sleep(max(self.period_s - (loop.time() - started_s), 0.0))
        finally:
            # Leaving any other way than q (SIGINT, SIGTERM, an error) cancels this loop:
            # the robot this monitor may have moved is stopped on the way out.
            if not client.closed and rov.commanded.sent_lock is not LockState.LOCKED:
                self._note_stop_unsent(rov)
                with contextlib.suppress(ClientError, TimeoutError, ConnectionError):
                    await asyncio.wait_for(rov.stop(), _STOP_WRITE_TIMEOUT_S)
            self._redraw()

    def _note_stop_unsent(self, rov: TrackedClient) -> None:
        """Leaving with the link down: the ``#stop!`` is only kept for a link that will not be
        reopened now."""
        if rov.link_down:
            self.stop_unsent = STOP_UNSENT_NOTICE

    def _on_event(self, event: Event) -> None:
        if isinstance(event, DebugText):
            self._last_message = visible(event.text)
        elif isinstance(event, BadFrame):
            raw = visible(event.raw.decode("ascii", errors="backslashreplace"))
            self._last_message = f"dropped reply {raw}: {event.detail}"
        else:
            return
        self._last_message_at_s = self._clock()

    def _on_client_event(self, event: ClientEvent) -> None:
        if isinstance(event, LinkState) and event.state == "reconnected":
            self.notify(REOPENED_NOTICE, title="link reopened", severity="warning", timeout=10)

    def _on_heard(self, _announcement: Announcement) -> None:
        """The controller announced a lock change this monitor did not send: said in full
        (the box may show it cut), and drawn now."""
        if self.rov is not None:
            self.notify(f"motors {self.rov.commanded.lock_text()}", severity="warning")
        self._redraw()

    def _on_sent(self, sent: SentFrame) -> None:
        if sent.warning is not None:
            self.notify(sent.warning, title=sent.text, severity="warning")

    # -- drawing --------------------------------------------------------------------------------

    def _redraw(self) -> None:
        with contextlib.suppress(NoMatches):  # the app is closing: the widgets are gone
            self._update_widgets()

    def _update_widgets(self) -> None:
        reading = self.readings.latest
        # Every box that shows the reading says it is old in the same words, not the depth alone.
        stale = stale_text(self.readings, now_s=self._clock(), period_s=self.period_s)
        self._stale = stale is not None
        for selector in _READING_BOXES:
            box = self.query_one(selector)
            box.set_class(self._stale, "-stale")
            if box.border_subtitle != (stale or ""):  # (set, it redraws the box, changed or not)
                box.border_subtitle = stale or ""
        digits = self.query_one("#depth-digits", Digits)
        depth = "—" if reading is None else str(reading.depth_cm)
        if digits.value != depth:  # (an update redraws it, changed or not)
            digits.update(depth)
        commanded = self.rov.commanded if self.rov is not None else None
        if commanded is not None:
            readout = depth_text(self.readings, commanded, stale=self._stale)
            if readout != self._depth_readout:  # (an update redraws it, changed or not)
                self._depth_readout = readout
                self.query_one("#depth-readout", Static).update(readout)
        leak = self.readings.leak
        leak_panel = self.query_one("#leak", Panel)
        if leak and not leak_panel.has_class("alarm"):
            self.bell()
        leak_panel.set_class(leak, "alarm")
        self.screen.set_class(leak, "leak")
        for panel in self.query(Panel):
            panel.refresh_if_changed()

    def _draw_small(self, width: int, height: int) -> RenderableType:
        rov = self.rov
        if rov is None:
            link = self._link_state
        elif rov.client.closed:
            link = "lost: keys send nothing"
        elif rov.link_down:
            link = "lost, reopening it"
        else:
            link = rov.health.status
        return small_screen_text(
            self.readings,
            rov.commanded if rov is not None else None,
            link,
            stale=stale_text(self.readings, now_s=self._clock(), period_s=self.period_s),
            size=(self.size.width, self.size.height),
            needed=self.needed_size,
        )

    def _draw_attitude(self, width: int, height: int) -> RenderableType:
        return attitude_text(self.readings, width, stale=self._stale)

    def _draw_commanded(self, width: int, height: int) -> RenderableType:
        if self.rov is None:
            return Text("nothing sent yet", style="dim")
        text = commanded_text(self.rov.commanded)
        if self._last_message:
            text.append(f"\n{'controller':<11}", style="dim")
            age_s = self._clock() - self._last_message_at_s
            text.append_text(
                controller_message_text(self._last_message, age_s=age_s, period_s=self.period_s)
            )
        return text

    def _draw_link(self, width: int, height: int) -> RenderableType:
        if self.rov is None:
            return Text(
                self._link_state, style="bold red" if "could not" in self._link_state else "yellow"
            )
        text = link_text(
            self._link_state,
            self.rov.health,
            self.rov.client.counters,
            self.readings,
            now_s=self._clock(),
            rate_hz=self.rate_hz,
            reopening=self.rov.link_down,
        )
        if self.rov.client.closed:  # (in the panel's four rows, instead of the health)
            return Text(f"{self._link_state}\nlink closed: keys send nothing", style="bold red")
        return text

    def _draw_chart(self, width: int, height: int) -> RenderableType:
        target_cm = self.rov.commanded.target_depth_cm if self.rov is not None else None
        lines = depth_chart(
            self.readings.history,
            now_s=self._clock(),
            window_s=self.readings.window_s,
            width=width,
            height=max(height - 2, 2),
            target_cm=target_cm,
        )
        text = Text("\n".join(lines))
        text.highlight_regex(f"{SAMPLE_MARK}+", "bold cyan")
        text.highlight_regex(f"{TARGET_MARK}+", "yellow")
        return text

    # -- keys -----------------------------------------------------------------------------------

    async def _send(self, *commands: Command) -> None:
        rov = self.rov
        if rov is None or rov.client.closed:
            self.notify("not connected: nothing sent", severity="error")
            return
        for command in commands:
            try:
                await rov.send(command)
            except ClientError as error:
                self.notify(str(error), title=str(command), severity="error")
                return
        self._redraw()

    async def action_stop(self) -> None:
        """``#stop!``: all motors off, locked (with the link down: kept, and said so)."""
        await self._send(Command("stop"))
        rov = self.rov
        if rov is not None and rov.link_down and not rov.client.closed:
            self.notify(STOP_KEPT_NOTICE, title="#stop! not sent yet", severity="error", timeout=10)

    async def action_start(self) -> None:
        """``#start!``: unlock."""
        await self._send(Command("start"))

    async def action_turn(self, step_deg: int) -> None:
        """``th`` with the direction turned by ``step_deg``."""
        if self.rov is not None:
            await self._send(controls.turn(self.rov.commanded, step_deg))

    async def action_power(self, step_percent: int) -> None:
        """``th`` with the power changed by ``step_percent``."""
        if self.rov is not None:
            await self._send(controls.change_power(self.rov.commanded, step_percent))

    async def action_depth(self, step_cm: int) -> None:
        """``mvd`` with the target moved by ``step_cm`` (after ``mvdirect 0`` if needed)."""
        if self.rov is not None:
            reading = self.readings.latest
            # A stale depth is no "depth now": the robot may have moved since (a silent link),
            # and a step deeper from where it was could send it up.
            stale = stale_text(self.readings, now_s=self._clock(), period_s=self.period_s)
            depth_now_cm = reading.depth_cm if reading is not None and stale is None else None
            try:
                commands = controls.change_depth_target(self.rov.commanded, depth_now_cm, step_cm)
            except controls.NoDepthReadingError as error:
                message = str(error)
                if reading is not None:  # (stale: "stale: 6.5 s old")
                    message = f"the depth reading is {stale}: {controls.FIRST_TARGET_TEXT}"
                self.notify(message, title="nothing sent", severity="warning")
                return
            await self._send(*commands)

    async def action_claw(self, frame_name: str) -> None:
        """``#h+!`` or ``#h-!``: one claw pulse."""
        await self._send(Command(frame_name))

    async def action_reset_leak(self) -> None:
        """``#slreset!``: clear the leak latch."""
        await self._send(Command("slreset"))

    async def action_quit_safely(self) -> None:
        """Leave; ``#stop!`` first unless the motors are locked as last sent."""
        rov = self.rov
        if rov is not None and not rov.client.closed:
            if rov.commanded.sent_lock is not LockState.LOCKED:
                self._note_stop_unsent(rov)
                await self._send(Command("stop"))
            await rov.close()  # (a poll waiting for its reply does not hold the exit up)
        self.exit()
