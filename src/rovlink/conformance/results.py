"""The outcome of a conformance run: one result per check, with the bytes that show a failure."""

from __future__ import annotations

from dataclasses import dataclass, field

from rovlink.conformance.wire import Exchange
from rovlink.protocol import COMMANDS
from rovlink.protocol.text_enum import StrEnum

__all__ = ["CheckResult", "Outcome", "Report"]

#: Commands that set a value the controller keeps and no query reads back.
_LASTING_SETTINGS = tuple(
    spec.name
    for spec in COMMANDS
    if not spec.is_query and not spec.motion and spec.setting is None and spec.arguments
)


class Outcome(StrEnum):
    """How a check ended."""

    PASSED = "pass"
    FAILED = "fail"
    SKIPPED = "skip"
    ABORTED = "abort"


@dataclass(frozen=True)
class CheckResult:
    """One check's outcome, its message and the exchanges it made (the evidence)."""

    name: str
    rules: tuple[str, ...]
    description: str
    outcome: Outcome
    message: str = ""
    duration_s: float = 0.0
    evidence: tuple[Exchange, ...] = ()

    @property
    def failed(self) -> bool:
        """Whether the check counts against the controller."""
        return self.outcome in (Outcome.FAILED, Outcome.ABORTED)


@dataclass
class Report:
    """Every result of a run, in order, and what the run wrote that outlives it."""

    target: str
    results: list[CheckResult] = field(default_factory=list)
    duration_s: float = 0.0
    #: What the failures suggest beyond themselves (the controller's checksum algorithm), if
    #: anything.
    hint: str | None = None
    #: The selected checks that did not run because a check aborted the run, in order.
    not_run: list[str] = field(default_factory=list)
    #: Why the checks in :attr:`not_run` did not run, when it was not the last check's abort
    #: (the run was interrupted).
    cut_short_by: str | None = None

    @property
    def stopped_because(self) -> str:
        """Why the run ended before :attr:`not_run`: ``<check> aborted the run``, or what cut it
        short."""
        if self.cut_short_by is not None:
            return self.cut_short_by
        return f"{self.results[-1].name} aborted the run" if self.results else "the run ended"

    @property
    def failures(self) -> list[CheckResult]:
        """The checks that failed or aborted the run."""
        return [result for result in self.results if result.failed]

    @property
    def passed(self) -> bool:
        """Whether no check failed and at least one passed, and the run was not cut short: a
        run of no checks proves nothing."""
        return not self.failures and self.count(Outcome.PASSED) > 0 and not self.cut_short_by

    @property
    def settings_sent(self) -> list[str]:
        """The lasting settings the run sent (``mgmp``, the PID gains, ``sdz``, ``sdk``), in
        the command table's order: no query reads them back, so the controller keeps the
        checks' test values until it is reset."""
        sent = b"".join(exchange.sent for result in self.results for exchange in result.evidence)
        return [name for name in _LASTING_SETTINGS if b"#" + name.encode() + b"." in sent]

    def count(self, outcome: Outcome) -> int:
        """How many checks ended so."""
        return sum(result.outcome is outcome for result in self.results)
