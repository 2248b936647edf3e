"""Which checksum algorithm the controller uses, when the suite's got no reply.

A suite run with another algorithm than the controller's fails every check of the checksum mode
with "no reply": each checksummed frame is dropped as damaged. That reads as a controller without
a checksum mode. So after such a run the suite tries the other known algorithms, and the report
says which one the controller answers.
"""

from __future__ import annotations

import dataclasses

from rovlink.client.errors import ConnectionLostError
from rovlink.client.links import Link
from rovlink.conformance.registry import NO_REPLY, CheckContext, SuiteOptions
from rovlink.conformance.results import Report
from rovlink.conformance.wire import Wire
from rovlink.protocol import ALGORITHMS, Command, Response, Setting, setting_command

__all__ = ["algorithm_hint"]

#: The checks of the checksum mode: their names start so.
_CHECKSUM_CHECKS = "checksum-"


def algorithm_hint(link: Link, options: SuiteOptions, report: Report) -> str | None:
    """What to tell the user when the checksum checks got no reply: the algorithm the controller
    answers a checksummed ``#qd`` with, or that none of the known ones got a reply either.
    ``None`` when no checksum check failed for want of a reply (nothing is sent then)."""
    if not any(
        result.name.startswith(_CHECKSUM_CHECKS) and NO_REPLY in result.message
        for result in report.failures
    ):
        return None
    others = [name for name in sorted(ALGORITHMS) if name != options.algorithm]
    try:
        if _answers_with(link, options):
            return None  # it answers with the suite's algorithm: the failures say what is wrong
        for name in others:
            if _answers_with(link, dataclasses.replace(options, algorithm=name)):
                return (
                    f"the checksum checks got no reply with {options.algorithm}, but the "
                    f"controller answers #qd checksummed with {name}: run with --algorithm {name}"
                )
    except ConnectionLostError:
        return None  # (the run's end says the link is lost)
    return (
        f"the checksum checks got no reply with {options.algorithm}, nor does the controller "
        f"answer #qd checksummed with {' or '.join(others)}: has it a checksum mode (P3)?"
    )


def _answers_with(link: Link, options: SuiteOptions) -> bool:
    """Whether, in checksum mode switched on with ``options.algorithm``, the controller answers
    ``#qd`` checksummed with it; the controller is put back in plain mode after."""
    context = CheckContext(
        Wire(link, algorithm=options.algorithm, baudrate=options.baudrate), options
    )
    context.restore()
    try:
        context.tell(context.frame(setting_command(Setting.CHECKSUM, True)))
        context.wire.replies_checksummed = True
        exchange = context.ask(context.frame(Command("qd"), checksum=True))
        return any(
            isinstance(frame.message, Response) and frame.message.name == "qd"
            for frame in exchange.valid_frames
        )
    finally:
        context.restore()  # (#crcoff! is matched exactly, without a checksum, P3)
