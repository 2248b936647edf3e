"""Drive the robot from typed lines or a script file, with the motion timeout as the dead-man.

Shows teleoperation without a gamepad: each line is a command as ``rovlink send`` reads it
(``start``, ``th 90 30``, ``mvd 100``, ``mvdirect 1`` then ``mvs -20``, ``qsa``, ``stop``;
``rovlink reference`` lists them), checked by ``rovlink.client.parse_command_text`` before
anything is sent, plus:

* ``wait SECONDS`` — pause the script;
* ``COMMAND for SECONDS`` — a thrust command (``th``, ``mvs``) renewed for that long, then
  zeroed: ``th 0 40 for 3`` drives ahead for three seconds.

The controller acts on motion only once unlocked (``start``), and on ``mvs`` only in direct
mode (``mvdirect 1``; ``mvdirect 0`` hands the vertical thrusters back to the depth hold,
``mvd``): anything else it drops without a word, as the protocol has no acknowledgements.

The dead-man is the client's ``motion_timeout`` (``--deadman``, 1 s by default): a thrust the
program does not renew within it is zeroed by the client, so a typed ``th 0 40`` moves the robot
for one second and a script or a person that stops sending stops the robot. Queries print their
replies. At the end of the input, on an error, on Ctrl-C, on SIGTERM (``kill``, ``systemctl
stop``), on SIGHUP (the terminal or the SSH session closed) and on SIGQUIT (Ctrl-\\) the robot
gets ``#stop!``.

A script file (``--script``) is checked whole before the robot is touched, so a mistake on
line 12 is reported before line 1 moves anything; typed lines are checked one by one (a wrong
one is reported and skipped).

Run it::

    python examples/script_teleop.py                        # type commands; the simulator
    python examples/script_teleop.py /dev/ttyUSB0 --script square.txt
    printf 'start\\nmvd 50\\nwait 5\\nth 0 40 for 3\\nqsa\\n' | python examples/script_teleop.py

Exit status: 0 at the end of the input, 1 on a driver error, 2 for a script with mistakes,
130 after Ctrl-C, SIGTERM, SIGHUP or SIGQUIT.
"""

from __future__ import annotations

import argparse
import logging
import re
import signal
import sys
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from types import FrameType

import rovlink
from rovlink.client import (
    Client,
    ClientError,
    ClientEvent,
    ConnectionLostError,
    parse_command_text,
    parse_url,
)
from rovlink.client.events import MotionExpired
from rovlink.protocol import Command

log = logging.getLogger("script_teleop")

#: The thrust commands the client's motion timeout covers (P23), and their zero.
THRUST_COMMANDS = ("th", "mvs")
_FOR = re.compile(r"^(?P<command>.*?)\s+for\s+(?P<seconds>\S+)$")
_WAIT = re.compile(r"^wait\s+(?P<seconds>\S+)$")


class ScriptError(ValueError):
    """A line that is not a valid step; the message names the line and what is wrong."""


@dataclass(frozen=True)
class Step:
    """One line of the script: a command (renewed for ``seconds`` if given) or a wait."""

    line_number: int
    command: Command | None
    seconds: float = 0.0


def parse_seconds(text: str, line_number: int) -> float:
    """A non-negative number of seconds; :class:`ScriptError` naming the line otherwise."""
    try:
        seconds = float(text)
    except ValueError:
        seconds = -1.0
    if not 0 <= seconds < 3600:
        raise ScriptError(f"line {line_number}: {text!r} is not a number of seconds (0–3600)")
    return seconds


def parse_line(text: str, line_number: int) -> Step | None:
    """The step of one line (None for a blank line or a ``#`` comment).

    >>> parse_line("th 0 40 for 3", 1)
    Step(line_number=1, command=Command(name='th', values=(0, 40)), seconds=3.0)
    """
    text = text.strip()
    if not text or (text.startswith("#") and not text.endswith("!")):
        return None  # ('#qd!' is a frame, '# dive' a comment)
    wait = _WAIT.match(text)
    if wait:
        return Step(line_number, None, parse_seconds(wait["seconds"], line_number))
    renewed = _FOR.match(text)
    seconds = 0.0
    if renewed:
        text = renewed["command"]
        seconds = parse_seconds(renewed["seconds"], line_number)
    try:
        command = parse_command_text(text)
    except ValueError as error:
        raise ScriptError(f"line {line_number}: {error}") from None
    if renewed and command.name not in THRUST_COMMANDS:
        raise ScriptError(
            f"line {line_number}: 'for' renews a thrust command ({', '.join(THRUST_COMMANDS)}), "
            f"not {command.name}"
        )
    return Step(line_number, command, seconds)


def parse_script(lines: Iterable[str]) -> list[Step]:
    """Every step of a script; :class:`ScriptError` listing every wrong line, if any."""
    steps: list[Step] = []
    errors: list[str] = []
    for line_number, text in enumerate(lines, start=1):
        try:
            step = parse_line(text, line_number)
        except ScriptError as error:
            errors.append(str(error))
            continue
        if step is not None:
            steps.append(step)
    if errors:
        raise ScriptError("\n".join(errors))
    return steps


def typed_steps(lines: Iterable[str]) -> Iterator[Step]:
    """Steps as they are typed; a wrong line is reported and skipped."""
    for line_number, text in enumerate(lines, start=1):
        try:
            step = parse_line(text, line_number)
        except ScriptError as error:
            print(error, flush=True)
            continue
        if step is not None:
            yield step


def zero_thrust(command: Command) -> Command:
    """The command that ends ``command``'s thrust: the same direction at 0 %, or no vertical."""
    if command.name == "th":
        return Command("th", (command.values[0], 0))
    return Command("mvs", (0,))


def run_step(rov: Client, step: Step, renew_every_s: float) -> None:
    """Send one step: a command (renewed and then zeroed with ``for``), or a wait."""
    if step.command is None:
        time.sleep(step.seconds)
        return
    replies = rov.send(step.command)
    for reply in replies:
        print(f"< {reply}", flush=True)
    if step.seconds:
        ends_at = time.monotonic() + step.seconds
        while (remaining_s := ends_at - time.monotonic()) > 0:
            time.sleep(min(renew_every_s, remaining_s))
            if time.monotonic() < ends_at:
                rov.send(step.command)
        rov.send(zero_thrust(step.command))


def report_dead_man(event: ClientEvent) -> None:
    """Say when the client zeroed a thrust nobody renewed (the dead-man let go)."""
    if isinstance(event, MotionExpired):
        frames = " ".join(str(command) for command in event.commands)
        print(f"dead-man: no thrust command renewed in time, sent {frames}", flush=True)


def teleoperate(
    url: str, steps: Iterable[Step], deadman_s: float, *, checksum: bool = False
) -> None:
    """Connect and run the steps; ``#stop!`` at the end however it ends."""
    with rovlink.connect(
        url, checksum=checksum, motion_timeout=deadman_s, on_event=report_dead_man
    ) as rov:
        print(f"connected to {rov.description}; dead-man {deadman_s:g} s", flush=True)
        try:
            for step in steps:
                run_step(rov, step, renew_every_s=deadman_s / 4)
        finally:
            try:
                rov.stop()
            except ConnectionLostError as error:
                # Nothing can be sent; the controller's link-loss failsafe stops the robot.
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
    """The command line: the URL (default ``sim://``), the script and the dead-man time."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "url", nargs="?", default="sim://", help="the robot's port or URL (default: sim://)"
    )
    parser.add_argument(
        "--script", metavar="FILE", help="read the commands from FILE (default: standard input)"
    )
    parser.add_argument(
        "--deadman",
        type=float,
        default=1.0,
        metavar="SECONDS",
        help="zero a thrust not renewed for this long (default: 1)",
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
    if not 0.05 <= args.deadman <= 10:
        parser.error(f"--deadman must be in 0.05–10 s, got {args.deadman:g}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the script or the typed lines; see the module's docstring for the exit status."""
    args = parse_arguments(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    steps: Iterable[Step]
    if args.script is not None:
        try:
            with open(args.script, encoding="utf-8") as script:
                steps = parse_script(script)
        except OSError as error:
            print(f"cannot read the script: {error}", file=sys.stderr)
            return 2
        except ScriptError as error:
            print(f"{args.script}: nothing sent:\n{error}", file=sys.stderr)
            return 2
    else:
        steps = typed_steps(sys.stdin)
    try:
        teleoperate(args.url, steps, args.deadman, checksum=args.checksum)
    except (ClientError, TimeoutError, ConnectionError) as error:
        log.error("%s", error)
        return 1
    except KeyboardInterrupt:
        print("interrupted", flush=True)
        return 130
    return 0


if __name__ == "__main__":
    take_termination_as_ctrl_c()
    sys.exit(main())
