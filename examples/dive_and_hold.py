"""Dive to a depth with the controller's depth hold, hold it, surface and lock.

Shows the shape of a mission script on the blocking client: refuse to start with the leak
latch set; unlock (``#start!``), leave direct-thrust mode and give the controller a target depth
(``#mvd.<cm>!``: its own PID holds it, so nothing expires while the script only watches); watch
the sensors until the depth has settled within a tolerance, with a deadline; hold it, watching
that it stays there (a controller that reset or stopped the motors comes back locked); surface
(``#mvd.0!``); lock (``#stop!``). A leak at any point aborts the dive and surfaces at once. The
``#stop!`` is in a ``finally``, so an error, a lost reply or Ctrl-C still ends with the motors
off and locked (and leaving the ``with`` block by an exception sends one too); so do SIGTERM
(``kill``, ``systemctl stop``), SIGHUP (the terminal or the SSH session closed) and SIGQUIT
(Ctrl-\\), which it takes as Ctrl-C.

Run it::

    python examples/dive_and_hold.py                                  # the simulator (sim://)
    python examples/dive_and_hold.py /dev/ttyUSB0 --depth 50 --hold 30
    python examples/dive_and_hold.py 'sim://?leak_at=3'               # a leak during the dive

Exit status: 0 when the dive was completed, 1 when it was aborted (a leak, a depth not reached
or lost, an error), 130 after Ctrl-C, SIGTERM, SIGHUP or SIGQUIT.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from types import FrameType

import rovlink
from rovlink.client import Client, ClientError, ConnectionLostError, Sensors, parse_url

log = logging.getLogger("dive_and_hold")

#: Readings in a row within the tolerance that count as "there" (one could be a wave).
SETTLED_READINGS = 3


class LeakDetectedError(Exception):
    """The leak sensor fired (``$q.l.1!``): the dive is aborted and the robot surfaced."""


class DepthNotReachedError(Exception):
    """The depth did not settle within the deadline: the dive goes no further."""


class DepthLostError(Exception):
    """The depth left the tolerance while holding: the controller reset (it comes back locked)
    or stopped the motors (its link-loss failsafe, a leak), a thruster failed. The dive goes no
    further."""


@dataclass(frozen=True)
class DivePlan:
    """The dive's numbers."""

    depth_cm: int = 100
    hold_s: float = 10.0
    tolerance_cm: int = 10
    reach_timeout_s: float = 60.0
    #: Between two readings of the sensors while waiting or holding.
    poll_interval_s: float = 0.2


def read_sensors(rov: Client, *, check_leak: bool = True) -> Sensors:
    """One reading of every sensor, printed; a leak raises :class:`LeakDetectedError`."""
    reading = rov.sensors()
    print(
        f"  depth {reading.depth_cm:4d} cm  heading {reading.heading_deg:3d}°  "
        f"leak {'YES' if reading.leak_detected else 'no'}",
        flush=True,
    )
    if check_leak and reading.leak_detected:
        raise LeakDetectedError(f"the leak sensor fired at {reading.depth_cm} cm")
    return reading


def wait_for_depth(rov: Client, target_cm: int, plan: DivePlan, *, check_leak: bool = True) -> int:
    """Read the sensors until the depth has settled within the tolerance; return it.

    :class:`DepthNotReachedError` after ``plan.reach_timeout_s``.
    """
    deadline = time.monotonic() + plan.reach_timeout_s
    settled = 0
    while True:
        depth_cm = read_sensors(rov, check_leak=check_leak).depth_cm
        settled = settled + 1 if abs(depth_cm - target_cm) <= plan.tolerance_cm else 0
        if settled >= SETTLED_READINGS:
            return depth_cm
        if time.monotonic() > deadline:
            raise DepthNotReachedError(
                f"{target_cm} cm not reached in {plan.reach_timeout_s:g} s (at {depth_cm} cm)"
            )
        time.sleep(plan.poll_interval_s)


def hold(rov: Client, plan: DivePlan) -> None:
    """Watch the sensors for ``plan.hold_s`` while the controller holds the depth.

    :class:`DepthLostError` when the depth has left the tolerance for ``SETTLED_READINGS``
    readings in a row: nothing else would tell (the controller answers queries as before).
    """
    deadline = time.monotonic() + plan.hold_s
    off_depth = 0
    while True:
        depth_cm = read_sensors(rov).depth_cm
        off_depth = off_depth + 1 if abs(depth_cm - plan.depth_cm) > plan.tolerance_cm else 0
        if off_depth >= SETTLED_READINGS:
            raise DepthLostError(
                f"lost the depth while holding {plan.depth_cm} ± {plan.tolerance_cm} cm: at "
                f"{depth_cm} cm for {off_depth} readings (did the controller reset or stop?)"
            )
        remaining_s = deadline - time.monotonic()
        if remaining_s <= 0:
            return
        time.sleep(min(plan.poll_interval_s, remaining_s))


def surface(rov: Client, plan: DivePlan) -> None:
    """Ask the depth hold for the surface and wait for it; a leak no longer stops the wait."""
    print("surfacing", flush=True)
    rov.hold_depth(0)
    try:
        depth_cm = wait_for_depth(rov, 0, plan, check_leak=False)
    except DepthNotReachedError as error:
        log.warning("%s; locking the motors anyway (the hull floats up)", error)
    else:
        print(f"at the surface ({depth_cm} cm)", flush=True)


def dive(rov: Client, plan: DivePlan) -> None:
    """The dive: unlock, dive, hold, surface. The caller sends ``#stop!`` however it ends."""
    if rov.leak_detected():
        raise LeakDetectedError(
            "the leak sensor had fired before the dive (the latch is set): look at the hull, "
            "then reset it with reset_leak()"
        )
    print("unlocking", flush=True)
    rov.start()
    rov.set_direct_mode(False)  # the vertical thrusters follow the depth PID, not #mvs
    print(f"diving to {plan.depth_cm} cm", flush=True)
    rov.hold_depth(plan.depth_cm)
    try:
        depth_cm = wait_for_depth(rov, plan.depth_cm, plan)
        print(f"holding {depth_cm} cm for {plan.hold_s:g} s", flush=True)
        hold(rov, plan)
    except LeakDetectedError as error:
        print(f"LEAK: {error}; aborting the dive", flush=True)
        surface(rov, plan)
        raise
    except (DepthNotReachedError, DepthLostError):
        surface(rov, plan)  # never stay at a depth nobody chose
        raise
    surface(rov, plan)


def stop_robot(rov: Client) -> None:
    """``#stop!``: motors off and locked. Never raises: it runs on the way out of everything."""
    try:
        rov.stop()
    except ConnectionLostError as error:
        # Nothing can be sent; the controller's link-loss failsafe stops the robot (P17).
        log.error("could not send #stop!: %s", error)
    else:
        print("motors off and locked", flush=True)


def take_termination_as_ctrl_c() -> None:
    """Have SIGTERM (``kill``, ``systemctl stop``), SIGHUP (the terminal or the SSH session
    closed) and SIGQUIT (Ctrl-\\) end the program as Ctrl-C does: through the ``finally`` that
    sends ``#stop!``.

    Python's default for each ends the process at once, running no ``finally``: the robot would
    keep its last command until the controller's link-loss failsafe stopped it. A signal ignored
    on entry (``nohup``) stays ignored.
    """

    def as_ctrl_c(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt(signal.Signals(signum).name)

    for name in ("SIGTERM", "SIGHUP", "SIGQUIT"):  # (Windows has neither of the last two)
        signum = getattr(signal, name, None)
        if signum is not None and signal.getsignal(signum) is signal.SIG_DFL:
            signal.signal(signum, as_ctrl_c)


def parse_arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line: the URL (default ``sim://``) and the dive's numbers."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "url", nargs="?", default="sim://", help="the robot's port or URL (default: sim://)"
    )
    parser.add_argument("--depth", type=int, default=100, metavar="CM", help="default: 100")
    parser.add_argument(
        "--hold", type=float, default=10.0, metavar="SECONDS", help="time at depth (default: 10)"
    )
    parser.add_argument(
        "--tolerance", type=int, default=10, metavar="CM", help="'at depth' within (default: 10)"
    )
    parser.add_argument(
        "--reach-timeout",
        type=float,
        default=60.0,
        metavar="SECONDS",
        help="time allowed to reach a depth (default: 60)",
    )
    parser.add_argument(
        "--interval",
        type=float,
        default=0.2,
        metavar="SECONDS",
        help="between two readings of the sensors (default: 0.2)",
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
    for option in ("hold", "tolerance", "reach_timeout"):
        value = getattr(args, option)
        if not value >= 0:  # (written so that NaN fails too: it would hold or wait for good)
            parser.error(f"--{option.replace('_', '-')} must be 0 or more, got {value:g}")
    if not 0.01 <= args.interval <= 10:
        parser.error(f"--interval must be in 0.01–10 s, got {args.interval:g}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the dive; see the module's docstring for the exit status."""
    args = parse_arguments(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    plan = DivePlan(args.depth, args.hold, args.tolerance, args.reach_timeout, args.interval)
    try:
        with rovlink.connect(args.url, checksum=args.checksum) as rov:
            try:
                dive(rov, plan)
            finally:
                stop_robot(rov)
    except (LeakDetectedError, DepthNotReachedError, DepthLostError) as error:
        print(f"dive aborted: {error}", flush=True)
        return 1
    except (ClientError, TimeoutError, ConnectionError) as error:
        log.error("dive aborted: %s", error)
        return 1
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        return 130
    print("dive completed", flush=True)
    return 0


if __name__ == "__main__":
    take_termination_as_ctrl_c()
    sys.exit(main())
