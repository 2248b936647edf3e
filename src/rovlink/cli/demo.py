"""``rovlink demo [URL]``: a scripted dive through the driver, with a live table of its progress.

Unlock, dive to a depth and hold it, move in a square, read every sensor one by one, surface,
lock. The script is :func:`run_dive` (it knows nothing of the terminal); the command renders its
progress with rich. Whatever happens — an error, Ctrl-C — the robot is sent ``#stop!``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import typer
from rich.console import Console, Group
from rich.live import Live
from rich.table import Table

import rovlink
from rovlink.cli.link_options import (
    DEFAULT_URL,
    AlgorithmOption,
    BaudrateOption,
    ChecksumOption,
    RetriesOption,
    TimeoutOption,
    UrlArgument,
)
from rovlink.protocol import DEFAULT_ALGORITHM

if TYPE_CHECKING:
    from rich.console import RenderableType

    from rovlink.client import Client, Sensors

__all__ = ["DivePlan", "Step", "register", "run_dive"]

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
    status: str = "waiting"  # waiting, running, done, not reached, skipped
    detail: str = ""
    started_at: float | None = None
    finished_at: float | None = None


@dataclass(slots=True)
class DiveProgress:
    """Everything the display shows: the steps and the latest reading."""

    steps: list[Step]
    started_at: float = field(default_factory=time.monotonic)
    latest: Sensors | None = None


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
                self.finish(step, "not reached",
                            f"{depth_cm} cm after {self.plan.reach_timeout_s:g} s")
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
        readings = (
            f"{rov.depth_cm()} cm, raw {rov.pressure_raw()}, "
            f"leak {'YES' if rov.leak_detected() else 'no'}, roll {rov.roll_deg():+d}°, "
            f"pitch {rov.pitch_deg():+d}°, heading {rov.heading_deg()}°"
        )
        self.finish(step, detail=readings)

    def run(self) -> DiveProgress:
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
        return self.progress


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
    steps = Table(title=f"rovlink demo — {url}", expand=False)
    steps.add_column("step", no_wrap=True)
    steps.add_column("", no_wrap=True)
    steps.add_column("time", justify="right", no_wrap=True)
    steps.add_column("result")
    marks = {"waiting": "[dim]·[/]", "running": "[yellow]…[/]", "done": "[green]✓[/]",
             "not reached": "[red]✗[/]", "skipped": "[dim]–[/]"}
    for step in progress.steps:
        elapsed = ""
        if step.started_at is not None:
            end = step.finished_at or time.monotonic()
            elapsed = f"{end - step.started_at:.1f} s"
        detail = step.detail if step.status == "done" else f"{step.status}: {step.detail}"
        steps.add_row(f"{step.name}\n[dim]{step.frames}[/]", marks[step.status], elapsed,
                      detail)
    sensors = Table(title="sensors (#qsa!)")
    for column in ("depth cm", "raw", "leak", "roll °", "pitch °", "heading °"):
        sensors.add_column(column, justify="right")
    reading = progress.latest
    if reading is not None:
        sensors.add_row(
            str(reading.depth_cm), str(reading.pressure_raw),
            "[red]YES[/]" if reading.leak_detected else "no",
            f"{reading.roll_deg:+d}", f"{reading.pitch_deg:+d}", str(reading.heading_deg),
        )
    return Group(steps, sensors)


def register(app: typer.Typer) -> None:
    """Add ``demo`` to the command line."""

    @app.command()
    def demo(  # noqa: PLR0917 - Typer reads the options from the parameters
        url: UrlArgument = DEFAULT_URL,
        depth_cm: int = typer.Option(100, "--depth", help="Dive depth, cm.", min=0, max=9999),
        hold_s: float = typer.Option(3.0, "--hold", help="Seconds to hold the depth.", min=0),
        leg_s: float = typer.Option(3.0, "--leg", help="Seconds per side of the square.", min=0),
        power_percent: int = typer.Option(
            30, "--power", help="Horizontal power on the square, %.", min=0, max=100
        ),
        reach_timeout_s: float = typer.Option(
            60.0, "--reach-timeout", help="Seconds allowed to reach a depth.", min=0
        ),
        checksum: ChecksumOption = False,
        algorithm: AlgorithmOption = DEFAULT_ALGORITHM,
        baudrate: BaudrateOption = None,
        timeout_s: TimeoutOption = 0.5,
        retries: RetriesOption = 2,
    ) -> None:
        """A scripted dive: unlock, dive and hold, a square, every sensor, surface, lock."""
        plan = DivePlan(depth_cm=depth_cm, hold_s=hold_s, leg_s=leg_s,
                        power_percent=power_percent, reach_timeout_s=reach_timeout_s)
        try:
            rov = rovlink.connect(url, checksum=checksum, algorithm=algorithm, baudrate=baudrate,
                                  timeout=timeout_s, retries=retries)
        except ValueError as error:
            raise typer.BadParameter(str(error), param_hint="URL") from None
        except ConnectionError as error:
            typer.echo(f"error: {error}", err=True)
            raise typer.Exit(1) from None
        console = Console()
        with rov, Live(console=console, refresh_per_second=8) as live:
            def show(progress: DiveProgress) -> None:
                live.update(_render(progress, url))

            try:
                progress = run_dive(rov, plan, show)
            except (TimeoutError, ConnectionError) as error:
                live.stop()
                typer.echo(f"error: {error} (the robot was sent #stop!)", err=True)
                raise typer.Exit(1) from None
        missed = [step.name for step in progress.steps if step.status != "done"]
        counters = rov.counters
        console.print(
            f"\n{counters.frames_sent} frames sent, {counters.replies} replies, "
            f"{counters.timeouts} timeouts, {counters.retries} retries"
        )
        if missed:
            typer.echo(f"not completed: {', '.join(missed)}", err=True)
            raise typer.Exit(1)
