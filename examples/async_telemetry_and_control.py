"""Stream telemetry in one asyncio task while another drives a pattern; a watchdog stops both.

Shows the asyncio client (``rovlink.aio.connect``) as a top-level program uses it:

* a telemetry task reads every sensor at a fixed rate (``rov.telemetry(rate_hz)``), prints each
  reading and shares the latest with the other tasks; a leak ends the run, and so does the
  depth lost while the pilot holds it (a controller that reset or stopped comes back locked);
* a pilot task unlocks, dives with the controller's depth hold, drives a square (renewing each
  ``move`` well within ``motion_timeout``, so a pilot that hangs lets the client zero the
  thrust), surfaces and locks;
* a watchdog task ends the run when telemetry goes stale (no reading for ``--stale`` seconds),
  and the whole run has a deadline (``--deadline``).

The first task to end decides: the pilot finishing is success, anything else cancels the others.
Cancellation is safe: the client's command methods never wait, so a task cancelled between two
commands leaves nothing half-sent; the ``finally`` sends ``#stop!`` however the run ended, and
leaving ``async with`` by an exception (a cancellation included) sends one too. Ctrl-C, SIGTERM
(``kill``, ``systemctl stop``), SIGHUP (the terminal or the SSH session closed) and SIGQUIT
(Ctrl-\\) cancel the run that way. It runs on Python 3.10 (no ``TaskGroup`` or
``asyncio.timeout``: ``asyncio.wait`` does the same here).

Run it::

    python examples/async_telemetry_and_control.py                   # the simulator (sim://)
    python examples/async_telemetry_and_control.py /dev/ttyUSB0 --depth 50 --power 20
    python examples/async_telemetry_and_control.py 'sim://?leak_at=4'  # a leak ends the run

Exit status: 0 when the pattern was completed, 1 when the run was aborted, 130 after Ctrl-C,
SIGTERM, SIGHUP or SIGQUIT.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import logging
import signal
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import rovlink.aio
from rovlink.aio import AsyncClient, ClientError, ConnectionLostError, Sensors
from rovlink.client import parse_url

log = logging.getLogger("async_telemetry_and_control")

#: The square: (name, direction clockwise from the bow in degrees).
LEGS = (("ahead", 0), ("starboard", 90), ("astern", 180), ("port", 270))

#: Readings in a row outside the tolerance that count as the depth lost (one could be a wave).
OFF_DEPTH_READINGS = 3


class RunAbortedError(Exception):
    """The run ended before the pattern was completed: a leak, stale telemetry, the deadline."""


@dataclass(frozen=True)
class Plan:
    """The run's numbers."""

    depth_cm: int = 50
    tolerance_cm: int = 10
    leg_s: float = 3.0
    power_percent: int = 30
    rate_hz: float = 5.0
    stale_s: float = 2.0
    deadline_s: float = 120.0
    #: Seconds after which the client zeroes a motion not renewed (P23); the pilot renews
    #: every ``motion_timeout_s / 4``.
    motion_timeout_s: float = 1.0


class Telemetry:
    """The latest reading, shared by the tasks; others wait for a condition on it."""

    def __init__(self) -> None:
        self.latest: Sensors | None = None
        self.received_at = asyncio.get_running_loop().time()
        #: The depth the pilot holds, cm, once there (None: diving or surfacing).
        self.holding_cm: int | None = None
        self._changed = asyncio.Condition()

    async def update(self, reading: Sensors) -> None:
        """Keep ``reading`` as the latest and wake whoever waits on one."""
        self.latest = reading
        self.received_at = asyncio.get_running_loop().time()
        async with self._changed:
            self._changed.notify_all()

    async def wait_for(self, predicate: Callable[[Sensors], bool]) -> Sensors:
        """Wait until a reading satisfies ``predicate``; return it."""
        async with self._changed:
            await self._changed.wait_for(lambda: self.latest is not None and predicate(self.latest))
        assert self.latest is not None
        return self.latest


async def stream_telemetry(rov: AsyncClient, plan: Plan, telemetry: Telemetry) -> None:
    """Print every reading and share it; a leak, or the depth the pilot holds lost for
    ``OFF_DEPTH_READINGS`` readings, raises :class:`RunAbortedError`."""
    off_depth = 0
    async for reading in rov.telemetry(plan.rate_hz):
        print(
            f"telemetry: depth {reading.depth_cm:4d} cm  heading {reading.heading_deg:3d}°  "
            f"roll {reading.roll_deg:+d}°  pitch {reading.pitch_deg:+d}°",
            flush=True,
        )
        await telemetry.update(reading)
        if reading.leak_detected:
            raise RunAbortedError(f"the leak sensor fired at {reading.depth_cm} cm")
        target_cm = telemetry.holding_cm
        off = target_cm is not None and abs(reading.depth_cm - target_cm) > plan.tolerance_cm
        off_depth = off_depth + 1 if off else 0
        if off_depth >= OFF_DEPTH_READINGS:
            raise RunAbortedError(
                f"lost the depth while holding {target_cm} ± {plan.tolerance_cm} cm: at "
                f"{reading.depth_cm} cm for {off_depth} readings "
                "(did the controller reset or stop?)"
            )
    # (telemetry() ends only by raising: a lost connection is a ConnectionLostError.)


async def at_depth(telemetry: Telemetry, target_cm: int, tolerance_cm: int) -> int:
    """Wait until the depth is within the tolerance of ``target_cm``; return it."""
    reading = await telemetry.wait_for(lambda r: abs(r.depth_cm - target_cm) <= tolerance_cm)
    return reading.depth_cm


async def drive_pattern(rov: AsyncClient, plan: Plan, telemetry: Telemetry) -> None:
    """Unlock, dive, drive the square, surface. The caller sends ``#stop!`` however it ends."""
    print("pilot: unlocking", flush=True)
    await rov.start()
    await rov.set_direct_mode(False)  # the vertical thrusters follow the depth PID
    await rov.hold_depth(plan.depth_cm)
    depth_cm = await at_depth(telemetry, plan.depth_cm, plan.tolerance_cm)
    print(f"pilot: at {depth_cm} cm", flush=True)
    telemetry.holding_cm = plan.depth_cm
    loop = asyncio.get_running_loop()
    renew_every_s = plan.motion_timeout_s / 4
    for name, direction_deg in LEGS:
        print(f"pilot: {name} ({direction_deg}°) at {plan.power_percent} %", flush=True)
        leg_ends_at = loop.time() + plan.leg_s
        while loop.time() < leg_ends_at:
            # Renewed in this task's loop: if this task hangs, the client zeroes the thrust
            # after motion_timeout (a MotionExpired event) instead of driving on.
            await rov.move(direction_deg, plan.power_percent)
            await asyncio.sleep(min(renew_every_s, max(leg_ends_at - loop.time(), 0.0)))
    await rov.move(0, 0)
    telemetry.holding_cm = None
    print("pilot: surfacing", flush=True)
    await rov.hold_depth(0)
    depth_cm = await at_depth(telemetry, 0, plan.tolerance_cm)
    print(f"pilot: at the surface ({depth_cm} cm)", flush=True)


async def watch_telemetry(plan: Plan, telemetry: Telemetry) -> None:
    """Raise :class:`RunAbortedError` when no reading has come for ``plan.stale_s``."""
    loop = asyncio.get_running_loop()
    while True:
        await asyncio.sleep(plan.stale_s / 4)
        silent_s = loop.time() - telemetry.received_at
        if silent_s > plan.stale_s:
            raise RunAbortedError(f"no telemetry for {silent_s:.1f} s")


async def run(rov: AsyncClient, plan: Plan) -> None:
    """Run the three tasks until the pilot finishes or one of them fails, then cancel the rest.

    Raises what ended the run if it was not the pilot finishing: :class:`RunAbortedError`, or a
    driver error (``ConnectionLostError``, ``QueryTimeoutError``).
    """
    telemetry = Telemetry()
    pilot = asyncio.create_task(drive_pattern(rov, plan, telemetry), name="pilot")
    tasks = {
        pilot,
        asyncio.create_task(stream_telemetry(rov, plan, telemetry), name="telemetry"),
        asyncio.create_task(watch_telemetry(plan, telemetry), name="watchdog"),
    }
    try:
        done, _ = await asyncio.wait(
            tasks, timeout=plan.deadline_s, return_when=asyncio.FIRST_COMPLETED
        )
    finally:
        # However this ends (a cancellation of run() itself included), no task outlives it.
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    if not done:
        raise RunAbortedError(f"the run took longer than its deadline of {plan.deadline_s:g} s")
    for task in done:
        error = task.exception()
        if error is not None:
            raise error
    if pilot not in done:
        ended = ", ".join(sorted(task.get_name() for task in done))
        raise RunAbortedError(f"the {ended} task ended on its own")


def cancel_on_termination(task: asyncio.Task[None]) -> None:
    """Have SIGTERM (``kill``, ``systemctl stop``), SIGHUP (the terminal or the SSH session
    closed) and SIGQUIT (Ctrl-\\) cancel ``task`` as Ctrl-C does, so that its ``finally`` sends
    ``#stop!``.

    Python's default for each ends the process at once, running no ``finally``: the robot would
    keep its last command until the controller's link-loss failsafe stopped it. A signal ignored
    on entry (``nohup``) stays ignored; the handlers go with the event loop.
    """
    loop = asyncio.get_running_loop()
    for name in ("SIGTERM", "SIGHUP", "SIGQUIT"):  # (Windows has neither of the last two)
        signum = getattr(signal, name, None)
        if signum is not None and signal.getsignal(signum) is signal.SIG_DFL:
            with contextlib.suppress(NotImplementedError):  # (Windows' loops take no signals)
                loop.add_signal_handler(signum, task.cancel)


async def run_and_stop(url: str, plan: Plan, *, checksum: bool = False) -> None:
    """Connect, run, and send ``#stop!`` however the run ends."""
    task = asyncio.current_task()
    assert task is not None
    cancel_on_termination(task)
    async with rovlink.aio.connect(
        url, checksum=checksum, motion_timeout=plan.motion_timeout_s
    ) as rov:
        try:
            await run(rov, plan)
        finally:
            # stop() never waits, so even a task being cancelled gets it out.
            try:
                await rov.stop()
            except ConnectionLostError as error:
                # Nothing can be sent; the controller's link-loss failsafe stops the robot.
                log.error("could not send #stop!: %s", error)
            else:
                print("motors off and locked", flush=True)


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line: the URL (default ``sim://``) and the run's numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "url", nargs="?", default="sim://", help="the robot's port or URL (default: sim://)"
    )
    parser.add_argument("--depth", type=int, default=50, metavar="CM", help="default: 50")
    parser.add_argument(
        "--leg", type=float, default=3.0, metavar="SECONDS", help="per side (default: 3)"
    )
    parser.add_argument("--power", type=int, default=30, metavar="PERCENT", help="default: 30")
    parser.add_argument(
        "--rate", type=float, default=5.0, metavar="HZ", help="telemetry rate (default: 5)"
    )
    parser.add_argument(
        "--stale",
        type=float,
        default=2.0,
        metavar="SECONDS",
        help="abort when no telemetry came for this long (default: 2)",
    )
    parser.add_argument(
        "--deadline",
        type=float,
        default=120.0,
        metavar="SECONDS",
        help="abort a run that takes longer (default: 120)",
    )
    parser.add_argument(
        "--checksum",
        action="store_true",
        help="checksum mode (CRC-8): a frame a noisy line damaged is dropped, never acted on",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="show the driver's log")
    args = parser.parse_args(argv)
    try:
        parse_url(args.url)  # as connect checks it: a typo is a usage error, not a traceback
    except ValueError as error:
        parser.error(str(error))
    if not 0 <= args.depth <= 9999:
        parser.error(f"--depth must be in 0–9999 cm, got {args.depth}")
    if not 0 <= args.power <= 100:
        parser.error(f"--power must be in 0–100 %, got {args.power}")
    for option in ("leg", "rate", "stale", "deadline"):
        value = getattr(args, option)
        if not value > 0:  # (written so that NaN fails too)
            parser.error(f"--{option} must be positive, got {value:g}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the pattern; see the module's docstring for the exit status."""
    args = parse_arguments(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    plan = Plan(
        depth_cm=args.depth,
        leg_s=args.leg,
        power_percent=args.power,
        rate_hz=args.rate,
        stale_s=args.stale,
        deadline_s=args.deadline,
    )
    try:
        asyncio.run(run_and_stop(args.url, plan, checksum=args.checksum))
    except RunAbortedError as error:
        print(f"run aborted: {error}", flush=True)
        return 1
    except (ClientError, TimeoutError, ConnectionError) as error:
        log.error("run aborted: %s", error)
        return 1
    except (KeyboardInterrupt, asyncio.CancelledError):  # Ctrl-C; SIGTERM, SIGHUP, SIGQUIT
        print("interrupted", flush=True)
        return 130
    print("pattern completed", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
