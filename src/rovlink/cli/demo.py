"""A scripted dive through the driver, with a live table of its progress.

Unlock, dive to a depth and hold it, move in a square, read every sensor one by one, surface,
lock. The script is :func:`run_dive` (it knows nothing of the terminal); the command renders its
progress with rich. Whatever happens — an error, Ctrl-C, a leak — the robot is sent ``#stop!``.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

from rovlink.cli import link_options
from rovlink.cli.failure import CommandError
from rovlink.cli.interrupt import (
    GatedClient,
    run_in_worker,
    say_stopped,
    send_stop,
    suspension_refused_by,
)
from rovlink.protocol import lookup

if TYPE_CHECKING:
    from rich.console import RenderableType
    from rich.live import Live

    from rovlink.client import Client, Sensors

__all__ = ["EPILOG", "DivePlan", "Step", "run_dive"]

EPILOG = """\
examples:
  rovlink demo                         on the simulator
  rovlink demo /dev/ttyUSB0 --checksum --depth 50 --hold 10"""

_POLL_INTERVAL_S = 0.2
_SETTLED_READINGS = 3  # consecutive readings within tolerance that count as "there"


@dataclass(frozen=True, slots=True)
class DivePlan:
    """The dive's numbers."""

    depth_cm: int = 100
    tolerance_cm: int = 10
    hold_s: float = 3.0
    leg_s: float = 3.0
    power_percent: int = 30
    reach_timeout_s: float = 60.0


@dataclass(slots=True)
class Step:
    """One step of the script and how it went."""

    name: str
    frames: str
    status: str = "waiting"  # waiting, running, done, not reached, aborted, skipped
    detail: str = ""
    started_at: float | None = None
    finished_at: float | None = None


@dataclass(slots=True)
class DiveProgress:
    """Everything the display shows: the steps and the latest reading."""

    steps: list[Step]
    started_at: float = field(default_factory=time.monotonic)
    latest: Sensors | None = None
    #: Why the dive was aborted (a leak), if it was.
    aborted: str | None = None


class _LeakError(Exception):
    """The leak sensor has fired (``$q.l.1!``): the dive ends at once with ``#stop!``."""


ProgressCallback = Callable[[DiveProgress], None]


def _steps(plan: DivePlan) -> list[Step]:
    p = plan.power_percent
    return [
        Step("unlock", "#start!"),
        Step(f"dive to {plan.depth_cm} cm", f"#mvdirect.0! #mvd.{plan.depth_cm}!"),
        Step(f"hold {plan.hold_s:g} s", "#qsa! …"),
        Step("square: ahead", f"#th.0.{p}!"),
        Step("square: right", f"#th.90.{p}!"),
        Step("square: astern", f"#th.180.{p}!"),
        Step("square: left", f"#th.270.{p}!"),
        Step("read every sensor", "#qd! #qr! #q.l! #qro! #qpi! #qhe!"),
        Step("surface", "#th.0.0! #mvd.0!"),
        Step("lock", "#stop!"),
    ]


class _Dive:
    def __init__(self, rov: Client, plan: DivePlan, on_progress: ProgressCallback) -> None:
        self.rov = rov
        self.plan = plan
        self.on_progress = on_progress
        self.progress = DiveProgress(_steps(plan))

    def begin(self, index: int) -> Step:
        step = self.progress.steps[index]
        step.status = "running"
        step.started_at = time.monotonic()
        self.on_progress(self.progress)
        return step

    def finish(self, step: Step, status: str = "done", detail: str = "") -> None:
        step.status = status
        step.detail = detail or step.detail
        step.finished_at = time.monotonic()
        self.on_progress(self.progress)

    def poll(self) -> Sensors:
        reading = self.rov.sensors()
        self.progress.latest = reading
        self.on_progress(self.progress)
        if reading.leak_detected:
            raise _LeakError
        return reading

    def watch(self, seconds: float) -> None:
        """Keep reading the sensors for ``seconds``."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.poll()
            time.sleep(min(_POLL_INTERVAL_S, max(deadline - time.monotonic(), 0.0)))

    def reach_depth(self, step: Step, target_cm: int) -> bool:
        """Read the sensors until the depth is within tolerance a few times running."""
        deadline = time.monotonic() + self.plan.reach_timeout_s
        settled = 0
        while True:
            depth_cm = self.poll().depth_cm
            settled = settled + 1 if abs(depth_cm - target_cm) <= self.plan.tolerance_cm else 0
            if settled >= _SETTLED_READINGS:
                self.finish(step, detail=f"at {depth_cm} cm")
                return True
            if time.monotonic() > deadline:
                self.finish(
                    step, "not reached", f"{depth_cm} cm after {self.plan.reach_timeout_s:g} s"
                )
                return False
            time.sleep(_POLL_INTERVAL_S)

    def hold_square_and_read(self, plan: DivePlan) -> None:
        """Hold the depth, move in a square, read every sensor."""
        rov = self.rov
        step = self.begin(2)
        self.watch(plan.hold_s)
        self.finish(step, detail=f"at {self.poll().depth_cm} cm")

        for index, direction_deg in enumerate((0, 90, 180, 270), start=3):
            step = self.begin(index)
            rov.move(direction_deg, plan.power_percent)
            self.watch(plan.leg_s)
            reading = self.poll()
            self.finish(step, detail=f"{reading.depth_cm} cm, heading {reading.heading_deg}°")
        rov.move(0, 0)

        step = self.begin(7)
        depth_cm, raw, leak = rov.depth_cm(), rov.pressure_raw(), rov.leak_detected()
        readings = (
            f"{depth_cm} cm, raw {raw}, leak {'YES' if leak else 'no'}, "
            f"roll {rov.roll_deg():+d}°, pitch {rov.pitch_deg():+d}°, heading {rov.heading_deg()}°"
        )
        self.finish(step, detail=readings)
        if leak:
            raise _LeakError

    def run(self) -> DiveProgress:
        """The dive; a leak, latched before it or fired during it, ends it at once with
        ``#stop!`` (a buoyant hull rises when its motors stop), as ``rovlink tune`` and the
        motion checks end on a leak: no script goes on diving with water coming in. A
        ``stop()`` from another thread that supersedes the dive's next command ends it too."""
        from rovlink.client import SupersededByStopError  # noqa: PLC0415 - the driver's

        steps = self.progress.steps
        why = "leak (q.l = 1)"
        locked_because = "leak"
        try:
            if self.rov.leak_detected():
                self.progress.aborted = (
                    "the leak sensor had fired before the dive (q.l = 1): look at the vehicle, "
                    "then reset the latch (slreset); the dive was not started"
                )
            else:
                self._dive()
        except _LeakError:
            self.rov.stop()
            during = next((step.name for step in steps if step.status == "running"), "the dive")
            self.progress.aborted = (
                f"the leak sensor fired (q.l = 1) during {during!r}: the dive was aborted and "
                "#stop! sent"
            )
        except SupersededByStopError as error:
            # The program's own stop() from another thread (a safety thread): the dive ends as
            # asked, without a retry of the command it superseded; the #stop! is out already.
            why = locked_because = "stop() called"
            during = next((step.name for step in steps if step.status == "running"), "the dive")
            self.progress.aborted = (
                f"stop() was called during {during!r}: the dive was aborted ({error.command} "
                "not sent)"
            )
        if self.progress.aborted is not None:
            if steps[-1].status == "waiting" and self.progress.latest is not None:  # (driven)
                self.finish(
                    self.begin(len(steps) - 1), detail=f"motors off and locked: {locked_because}"
                )
            for step in steps:
                if step.status in ("running", "waiting"):
                    status = "aborted" if step.status == "running" else "skipped"
                    self.finish(step, status, why)
        return self.progress

    def _dive(self) -> None:
        rov, plan = self.rov, self.plan
        rov.start()
        self.finish(self.begin(0))

        step = self.begin(1)
        rov.set_direct_mode(False)
        rov.hold_depth(plan.depth_cm)
        if self.reach_depth(step, plan.depth_cm):
            self.hold_square_and_read(plan)
        else:
            # Never move on at a depth nobody chose: straight to surfacing and locking.
            for skipped in self.progress.steps[2:8]:
                self.finish(skipped, "skipped", "the dive depth was not reached")

        step = self.begin(8)
        rov.hold_depth(0)
        self.reach_depth(step, 0)

        step = self.begin(9)
        rov.stop()
        self.finish(step, detail="motors off and locked")


def run_dive(rov: Client, plan: DivePlan, on_progress: ProgressCallback) -> DiveProgress:
    """Run the scripted dive on a connected client; ``#stop!`` is sent however it ends.

    Example::

        with rovlink.connect("sim://") as rov:
            run_dive(rov, DivePlan(depth_cm=50), on_progress=print)
    """
    try:
        return _Dive(rov, plan, on_progress).run()
    finally:
        if not rov.closed:
            rov.stop()


def _render(progress: DiveProgress, url: str) -> RenderableType:
    from rich.console import Group  # noqa: PLC0415 - rich loads only for this command
    from rich.table import Table  # noqa: PLC0415

    steps = Table(title=f"rovlink demo — {url}", expand=False)
    steps.add_column("step", no_wrap=True)
    steps.add_column("", no_wrap=True)
    steps.add_column("time", justify="right", no_wrap=True)
    steps.add_column("result")
    marks = {
        "waiting": "[dim]·[/]",
        "running": "[yellow]…[/]",
        "done": "[green]✓[/]",
        "not reached": "[red]✗[/]",
        "aborted": "[red]✗[/]",
        "skipped": "[dim]–[/]",
    }
    for step in progress.steps:
        elapsed = ""
        if step.started_at is not None:
            end = step.finished_at or time.monotonic()
            elapsed = f"{end - step.started_at:.1f} s"
        detail = step.detail if step.status == "done" else f"{step.status}: {step.detail}"
        steps.add_row(f"{step.name}\n[dim]{step.frames}[/]", marks[step.status], elapsed, detail)
    sensors = Table(title="sensors (#qsa!)")
    for column in ("depth cm", "raw", "leak", "roll °", "pitch °", "heading °"):
        sensors.add_column(column, justify="right")
    reading = progress.latest
    if reading is not None:
        sensors.add_row(
            str(reading.depth_cm),
            str(reading.pressure_raw),
            "[red]YES[/]" if reading.leak_detected else "no",
            f"{reading.roll_deg:+d}",
            f"{reading.pitch_deg:+d}",
            str(reading.heading_deg),
        )
    return Group(steps, sensors)


def _percent(text: str) -> int:
    return link_options.bounded_int(text, 0, 100)


def _depth_cm(text: str) -> int:
    """A dive depth, cm, in the range of ``#mvd`` (the command table's)."""
    target = lookup("mvd").arguments[0]
    return link_options.bounded_int(text, target.minimum, target.maximum)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``demo``'s options."""
    link_options.add_link_options(parser)
    dive = parser.add_argument_group("the dive")
    dive.add_argument(
        "--depth",
        dest="depth_cm",
        type=_depth_cm,
        default=100,
        metavar="CM",
        help=f"dive depth, cm, {lookup('mvd').arguments[0].range_text()} (default: %(default)s)",
    )
    dive.add_argument(
        "--hold",
        dest="hold_s",
        type=link_options.seconds,
        default=3.0,
        metavar="SECONDS",
        help="time to hold the depth (default: %(default)s)",
    )
    dive.add_argument(
        "--leg",
        dest="leg_s",
        type=link_options.seconds,
        default=3.0,
        metavar="SECONDS",
        help="time per side of the square (default: %(default)s)",
    )
    dive.add_argument(
        "--power",
        dest="power_percent",
        type=_percent,
        default=30,
        metavar="PERCENT",
        help="horizontal power on the square, 0–100 (default: %(default)s)",
    )
    dive.add_argument(
        "--reach-timeout",
        dest="reach_timeout_s",
        type=link_options.seconds,
        default=60.0,
        metavar="SECONDS",
        help="time allowed to reach a depth (default: %(default)s)",
    )


def _take_down(live: Live) -> None:
    """Stop the live table; a closed terminal (its window gone) is no reason to stop leaving."""
    with contextlib.suppress(OSError):
        live.stop()


def run(args: argparse.Namespace) -> int:
    """Run the dive with a live table; exit status 1 unless every step was done."""
    from rich.live import Live  # noqa: PLC0415

    from rovlink.cli.rich_console import TableConsole  # noqa: PLC0415

    plan = DivePlan(
        depth_cm=args.depth_cm,
        hold_s=args.hold_s,
        leg_s=args.leg_s,
        power_percent=args.power_percent,
        reach_timeout_s=args.reach_timeout_s,
    )
    rov = link_options.connect(args, keepalive_s=1.0)
    gate = GatedClient(rov)
    console = TableConsole()
    # A suspended demo could not stop the robot: the leg it was on would go on unattended
    # (or until the controller's watchdog), and back in the foreground the dive would carry on
    # and call each step done after the watchdog had locked the motors. (Said above the live
    # table, which takes what goes to stderr meanwhile.)
    with (
        link_options.closing_unless_interrupted(rov),
        suspension_refused_by("rovlink demo"),
        Live(console=console, refresh_per_second=8) as live,
    ):

        def show(progress: DiveProgress) -> None:
            live.update(_render(progress, args.url))

        try:
            progress = run_in_worker(lambda: run_dive(cast("Client", gate), plan, show))
        except KeyboardInterrupt:
            # #stop! first: taking the table down writes to a terminal that may be closed.
            outcome = gate.stop_for_good()
            _take_down(live)
            say_stopped("rovlink demo", outcome)
            raise
        except (TimeoutError, ConnectionError) as error:
            outcome = send_stop(rov)  # (again if the dive's end sent it: said as it went)
            _take_down(live)
            say_stopped("rovlink demo", outcome)
            raise CommandError(str(error)) from None
    missed = [step.name for step in progress.steps if step.status != "done"]
    counters = rov.counters
    console.print(
        f"\n{counters.frames_sent} frames sent, {counters.replies} replies, "
        f"{counters.timeouts} timeouts, {counters.retries} retries"
    )
    if progress.aborted is not None:
        raise CommandError(progress.aborted)
    if missed:
        print(f"rovlink demo: not completed: {', '.join(missed)}", file=sys.stderr)
        return 1
    return 0
