"""Run the checks against one controller and collect a :class:`Report`."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import Link
from rovlink.conformance import checksums, debug, framing, lock, motion, replies, sets
from rovlink.conformance.algorithm_probe import algorithm_hint
from rovlink.conformance.registry import (
    CHECKS,
    LATE_WAIT_FACTOR,
    Check,
    CheckAbortedError,
    CheckContext,
    CheckFailedError,
    CheckSkippedError,
    SuiteOptions,
)
from rovlink.conformance.results import CheckResult, Outcome, Report
from rovlink.conformance.wire import Wire
from rovlink.logs import get_logger
from rovlink.protocol import BadFrame, Command, Response
from rovlink.protocol.visible import visible

__all__ = ["PreflightError", "run_checks", "select_checks"]

logger = get_logger(__name__)

# The modules register their checks when imported; this is the order they run in.
_MODULES = (replies, framing, sets, checksums, debug, lock, motion)


class PreflightError(Exception):
    """The controller cannot be checked as it is (no answer, a leak latched)."""


def select_checks(names: Sequence[str] = (), *, motion: bool = False) -> list[Check]:
    """The checks to run: all (motion ones only with ``motion``), or those named/prefixed.

    Raises ValueError for a name that selects nothing that may run: no check, or only motion
    checks without ``motion`` (dropping them silently left a run of no checks that passed).
    """
    # Motion checks last: the others leave the vehicle locked and still.
    ordered = [item for item in CHECKS if not item.motion] + [c for c in CHECKS if c.motion]
    chosen = [item for item in ordered if motion or not item.motion]
    if not names:
        return chosen
    if not all(names):  # ("" is a prefix of every name: it would run them all)
        raise ValueError("an empty check name: name a check or the start of one (see --list)")
    for name in names:
        _check_name_selects(name, chosen)
    return [item for item in chosen if any(item.name.startswith(name) for name in names)]


def _check_name_selects(name: str, allowed: Sequence[Check]) -> None:
    """Raise ValueError unless ``name`` starts the name of a check in ``allowed``."""
    if any(item.name.startswith(name) for item in allowed):
        return
    if any(item.name.startswith(name) for item in CHECKS):
        raise ValueError(f"{name!r} names only motion checks: they run only with --motion")
    raise ValueError(f"no check is named {name!r} (see --list)")


def run_checks(
    link: Link,
    target: str,
    options: SuiteOptions | None = None,
    checks: Sequence[Check] | None = None,
    on_result: Callable[[CheckResult], None] | None = None,
) -> Report:
    """Run ``checks`` (default: every check the options allow) over ``link``.

    Before the first check the controller must answer ``#q.l!`` with no leak latched. Between
    checks it is put back in checksum and debug mode off, locked, depth mode. The run ends with
    ``#stop!``, whatever happened.
    """
    options = options or SuiteOptions()
    wire = Wire(link, algorithm=options.algorithm, baudrate=options.baudrate)
    selected = list(checks) if checks is not None else select_checks(motion=options.motion)
    report = Report(target)
    started = time.monotonic()
    try:
        _preflight(wire, options)
        for index, item in enumerate(selected):
            result = _run_one(item, wire, options)
            report.results.append(result)
            if on_result is not None:
                on_result(result)
            if result.outcome is Outcome.ABORTED:
                report.not_run = [later.name for later in selected[index + 1 :]]
                break
        else:
            report.hint = algorithm_hint(link, options, report)
    finally:
        try:
            link.write(b"#crcoff!#stop!#debug0!")
        except ConnectionLostError:
            logger.warning("could not send the final #stop!: the link is lost")
        report.duration_s = time.monotonic() - started
    return report


def _preflight(wire: Wire, options: SuiteOptions) -> None:
    """Wait for the controller to answer ``#q.l!`` (a board may boot for up to 2 s after its
    port opens, P21), and refuse to go on if its leak latch is set or the link is lost."""
    try:
        leak = _wait_for_answer(wire, options)
    except ConnectionLostError as error:
        raise PreflightError(
            f"the link was lost before the first check: {error}{_what_it_said(wire)}"
        ) from None
    if leak == (1,):
        raise PreflightError(
            "the leak latch is set: inspect the vehicle, then send #slreset! before checking"
        )


def _what_it_said(wire: Wire) -> str:
    """``; it said: "…"`` with the last line of text the controller sent, if any (a server
    that turns the suite away says why: another client is being served)."""
    lines = [line for exchange in wire.log for line in exchange.text]
    return f'; it said: "{visible(lines[-1].text)}"' if lines else ""


def _wait_for_answer(wire: Wire, options: SuiteOptions) -> tuple[int, ...]:
    """The values of the controller's first ``$q.l`` reply to a plain ``#q.l!``, waited for up
    to the boot time; PreflightError if none comes."""
    context = CheckContext(wire, options)
    deadline = time.monotonic() + options.boot_timeout_s
    first = len(wire.log)  # (what came while the restores were sent is said too: a banner)
    attempts = 0
    while True:
        attempts += 1
        context.restore(deadline - time.monotonic())
        # Longer than a check waits (a slow answer here is for the checks to report, and the
        # restore before the next attempt would read it and throw it away), but not past the
        # boot time unless a check's own wait is longer.
        wait_s = max(deadline - time.monotonic(), options.reply_timeout_s)
        exchange = wire.send(
            context.frame(Command("q.l")),
            frames=1,
            timeout_s=min(LATE_WAIT_FACTOR * options.reply_timeout_s, wait_s),
            linger_s=0.02,
        )
        values = [
            frame.message.values
            for frame in exchange.valid_frames
            if isinstance(frame.message, Response) and frame.message.name == "q.l"
        ]
        if values:
            if attempts > 1:
                # The answer may be a late one to an earlier attempt: the rest are let come
                # now, or they would land in the first checks' waits.
                wire.drain(LATE_WAIT_FACTOR * options.reply_timeout_s)
            break
        if time.monotonic() >= deadline:
            since = wire.log[first:]
            received = b"".join(exchange.received for exchange in since)
            # (a reply the decoder refused is named with why: a checksum on a plain reply)
            invalid = [
                frame for item in since for frame in item.frames if isinstance(frame, BadFrame)
            ]
            why = (
                f"; {invalid[-1].raw!r} is no valid frame: {invalid[-1].detail}" if invalid else ""
            )
            raise PreflightError(
                f"the controller did not answer #q.l! within {options.boot_timeout_s:g} s "
                f"(received {received[-200:]!r}){why}"
            )
    return values[0]


def _stopped_answering(wire: Wire, options: SuiteOptions) -> str | None:
    """After a failed check: what to add to its failure if the controller no longer answers a
    plain ``#q.l!``, given the boot time (it may have reset, P21); None if it does. Every
    later check would fail for want of a reply, and blame its own rule."""
    try:
        _wait_for_answer(wire, options)
    except PreflightError:
        return (
            f"; then a plain #q.l! got no reply within {options.boot_timeout_s:g} s either: the "
            "controller stopped answering (hung, or reset and not back), run aborted"
        )
    return None


def _run_one(item: Check, wire: Wire, options: SuiteOptions) -> CheckResult:
    context = CheckContext(wire, options)
    started = time.monotonic()
    outcome, message = Outcome.PASSED, ""
    try:
        context.restore()
        if item.motion and not options.motion:
            raise CheckSkippedError("motion checks need --motion")
        item.run(context)
    except CheckFailedError as failure:
        outcome, message = Outcome.FAILED, str(failure)
        try:
            silent = _stopped_answering(wire, options)
        except ConnectionLostError as error:
            silent = f"; then the link was lost: {error}"
        if silent is not None:
            outcome, message = Outcome.ABORTED, message + silent
    except CheckSkippedError as skip:
        outcome, message = Outcome.SKIPPED, str(skip)
    except CheckAbortedError as abort:
        outcome, message = Outcome.ABORTED, str(abort)
    except ConnectionLostError as error:
        outcome, message = Outcome.ABORTED, f"link lost: {error}"
    logger.debug("%s: %s %s", item.name, outcome, message)
    return CheckResult(
        name=item.name,
        rules=item.rules,
        description=item.description,
        outcome=outcome,
        message=message,
        duration_s=time.monotonic() - started,
        evidence=tuple(context.exchanges),
    )
