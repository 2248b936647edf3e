"""Replaying a recording's commands to a controller and comparing its replies with the recorded
ones: how a firmware author checks a new build against last week's dive.

The program's own commands are replayed (not the driver's keep-alives, retries and fences: the
replaying driver makes its own), and the driver's own frames that set the motion or the lock
(an expired motion's zero thrust, a ``#stop!`` kept for a reopened link), at their recorded
times. Each query's replies are compared value
by value with the recorded replies, within ``tolerance`` (flags such as the leak latch exactly).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field

from rovlink.protocol import Command, Response, Setting, encode
from rovlink.recorder.entries import Entry, EventEntry, FrameEntry
from rovlink.recorder.playback import wait_until

__all__ = [
    "Divergence",
    "ReplayStep",
    "ReplaySummary",
    "drivers_checksum_mode",
    "replay_steps",
    "run_replay",
]


@dataclass
class ReplayStep:
    """One command of the program, when it was sent, and (for a query) what it got then:
    ``None`` if no reply was recorded (the query failed)."""

    t_s: float
    command: Command
    recorded: list[Response] | None = None
    expected_count: int = 0


@dataclass(frozen=True)
class Divergence:
    """A query whose replies differ from the recorded ones."""

    t_s: float
    query: str
    recorded: str
    replayed: str

    def __str__(self) -> str:
        return f"{self.t_s:9.3f} s  {self.query}: recorded {self.recorded}, now {self.replayed}"


@dataclass
class ReplaySummary:
    """What a replay found."""

    commands_sent: int = 0
    queries_compared: int = 0
    identical: int = 0
    divergences: list[Divergence] = field(default_factory=list)


def replay_steps(entries: Iterable[Entry]) -> list[ReplayStep]:
    """The program's commands in a recording, each query with its recorded replies.

    A query that failed (a ``query_failed`` event) awaits the driver's retry, and is answered
    by the retry's replies; without one, the failure was final and the query recorded no reply
    (the later replies of its name are the later queries'). The driver's events mark each
    retry (a frame's ``retry``); in a recording without the marks (a tap's, an older one) the
    retry is taken to be the next command of its name (the driver's fence may come first), and
    the failure final if a command of another name comes first. A query whose reply the
    recording ends before (a ``--split`` part, a killed recorder) is resent but not compared:
    what it got is not known.
    """
    steps: list[ReplayStep] = []
    # Per name, the queries awaiting replies in the order they went; with retries marked, the
    # driver's own (keep-alives, fences: None) among them, whose replies are no program's.
    awaiting: dict[str, deque[ReplayStep | None]] = {}
    failed: set[str] = set()  # names whose oldest awaiting query failed, a retry not yet seen
    # With retries marked: the queries that failed, per name, oldest first, awaiting a retry.
    retrying: dict[str, deque[ReplayStep]] = {}
    marked = False  # the recording marks retries (a command's ``retry`` is not None)
    for entry in entries:
        if isinstance(entry, EventEntry):
            queue = awaiting.get(entry.name)
            if entry.event != "query_failed" or not queue:
                continue
            failing = queue[0]
            if failing is None:  # (the driver's own query failed: it makes another)
                queue.popleft()
                continue
            failing.recorded = None  # (a part of a reply: discarded)
            if marked:  # it awaits its retry, if one comes, and no reply until then
                retrying.setdefault(entry.name, deque()).append(failing)
                queue.popleft()
            else:
                failed.add(entry.name)
            continue
        if not isinstance(entry, FrameEntry):
            continue
        if entry.direction == "out" and entry.kind == "command":
            marked |= entry.retry is not None
            if entry.retry:
                retried = retrying.get(entry.name)
                if retried:  # awaits its replies again, now behind the queries sent before
                    awaiting.setdefault(entry.name, deque()).append(retried.popleft())
                continue
            if entry.name in failed:
                # Its retry (the driver's, in whichever way it marks it; a program that asks
                # again at once after a final failure cannot be told from one): the query
                # awaits its reply still.
                failed.discard(entry.name)
                continue
            if entry.by_session and not _moves_or_locks(entry):
                if marked and entry.kind == "command" and Command(entry.name).spec.is_query:
                    awaiting.setdefault(entry.name, deque()).append(None)
                continue  # (a fence, a keep-alive, a mode frame: no retry and no decision)
            for name in failed:  # the program went on: those failures were final
                awaiting[name].popleft()
            failed.clear()
            command = Command(entry.name, entry.values)
            step = ReplayStep(entry.t_s, command, expected_count=len(command.spec.replies))
            steps.append(step)
            if step.expected_count:
                awaiting.setdefault(command.name, deque()).append(step)
        elif entry.direction == "in" and entry.query is not None and not entry.late:
            queue = awaiting.get(entry.query)
            if not queue:
                continue  # answers a query of the driver's own (a keep-alive)
            answered = queue[0]
            if answered is None:  # (a keep-alive, a fence: one reply each)
                queue.popleft()
                continue
            if answered.recorded is None:
                answered.recorded = []
            answered.recorded.append(Response(entry.name, entry.values))
            if len(answered.recorded) >= answered.expected_count:
                queue.popleft()
    for name, queue in awaiting.items():
        for waiting in queue:
            if waiting is None:
                continue
            if name not in failed:  # (a failure the recording ends on: no reply, as recorded)
                waiting.expected_count = 0
            failed.discard(name)  # (only the oldest had failed)
    return steps


def drivers_checksum_mode(entry: Entry) -> bool | None:
    """The checksum mode ``entry`` shows the recording's driver asking for: its own mode frame
    (``#crcon!``, ``#crcoff!``, written as it connects, P3); None for any other entry.

    The header says the mode the recording starts in, which for a driver is off (its connect
    probe and mode frame go plain); the mode its program asked for is its mode frame's.

    >>> drivers_checksum_mode(FrameEntry(1.0, 1, "out", "command", "crcon", (), by_session=True))
    True
    >>> drivers_checksum_mode(FrameEntry(1.0, 1, "out", "command", "crcon", ()))  # a program's
    """
    if not (
        isinstance(entry, FrameEntry)
        and entry.direction == "out"
        and entry.kind == "command"
        and entry.by_session
    ):
        return None
    try:
        setting = Command(entry.name, entry.values).setting
    except ValueError:  # (a name no command has: a damaged or foreign recording)
        return None
    return setting[1] if setting is not None and setting[0] is Setting.CHECKSUM else None


def _moves_or_locks(entry: FrameEntry) -> bool:
    """Whether a frame the driver wrote itself set the robot's motion or lock: the zero thrust
    of an expired motion (P23) or of a reopened link, a ``#stop!`` kept for a reopened link.
    The controller acted on them as on the program's, so a replay sends them where they were
    (the replaying driver expires no motion of its own: at another ``--speed`` it would at
    other points of the session)."""
    spec = Command(entry.name, entry.values).spec
    return not spec.is_query and (spec.motion or spec.setting is Setting.LOCKED)


def _text(responses: Iterable[Response] | None) -> str:
    if responses is None:
        return "no reply"
    return "".join(encode(response).decode("ascii") for response in responses)


def _changes(
    recorded: list[Response] | None, replayed: tuple[Response, ...] | None, tolerance: int
) -> tuple[str, str]:
    """The two sides of a difference: the replies that differ beyond ``tolerance`` only, when
    the same replies came (a pitch within it is no part of the difference); all otherwise."""
    if recorded is None or replayed is None or not _same_names(recorded, replayed):
        return _text(recorded), _text(replayed)
    pairs = [
        (old, new)
        for old, new in zip(recorded, replayed, strict=True)
        if _differs(old, new, tolerance)
    ]
    return _text(old for old, _ in pairs), _text(new for _, new in pairs)


def _same_names(recorded: list[Response], replayed: tuple[Response, ...]) -> bool:
    return [r.name for r in recorded] == [r.name for r in replayed]


def _differs(old: Response, new: Response, tolerance: int) -> bool:
    for argument, a, b in zip(old.spec.arguments, old.values, new.values, strict=True):
        # A flag (the leak latch) is on or off: no tolerance makes 0 and 1 the same.
        allowed = tolerance if argument.maximum - argument.minimum > 1 else 0
        if abs(a - b) > allowed:
            return True
    return False


def _same(
    recorded: list[Response] | None, replayed: tuple[Response, ...] | None, tolerance: int
) -> bool:
    if recorded is None or replayed is None:
        return recorded is None and replayed is None
    if not _same_names(recorded, replayed):
        return False
    return not any(
        _differs(old, new, tolerance) for old, new in zip(recorded, replayed, strict=True)
    )


def run_replay(
    steps: list[ReplayStep],
    send: Callable[[Command], tuple[Response, ...] | None],
    *,
    speed: float = 1.0,
    tolerance: int = 0,
    origin_s: float | None = None,
    sleep: Callable[[float], None] = time.sleep,
    clock: Callable[[], float] = time.monotonic,
) -> Iterator[tuple[ReplayStep, tuple[Response, ...] | None, Divergence | None]]:
    """Send each step at its recorded time (divided by ``speed``; 0: no waiting) with ``send``
    (``None`` back: the query got no reply) and yield it with what came back and the
    divergence, if any, timed from ``origin_s`` (the recording's start, where ``rovlink
    replay`` counts from; default: the first step)."""
    if not steps:
        return
    first_s = steps[0].t_s
    origin_s = first_s if origin_s is None else origin_s
    started_s = clock()
    for step in steps:
        if speed > 0:
            wait_until(started_s + (step.t_s - first_s) / speed, sleep=sleep, clock=clock)
        replayed = send(step.command)
        divergence = None
        if step.expected_count and not _same(step.recorded, replayed, tolerance):
            divergence = Divergence(
                step.t_s - origin_s,
                step.command.name,
                *_changes(step.recorded, replayed, tolerance),
            )
        yield step, replayed, divergence
