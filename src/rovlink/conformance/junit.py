"""JUnit XML for a firmware CI: one test case per check, failures with their evidence bytes."""

from __future__ import annotations

from pathlib import Path
from xml.etree import ElementTree

from rovlink.conformance.results import Outcome, Report
from rovlink.conformance.wire import Exchange

__all__ = ["evidence_text", "junit_not_started", "junit_xml", "write_junit"]


def evidence_text(evidence: tuple[Exchange, ...], limit: int = 8) -> str:
    """The exchanges as lines ``sent: b'…'`` / ``received: b'…'`` (the last ``limit``)."""
    lines = []
    for exchange in evidence[-limit:]:
        lines.append(f"sent:     {exchange.sent!r}")
        lines.append(f"received: {exchange.received!r}")
    return "\n".join(lines)


def junit_xml(report: Report, suite_name: str = "rovlink check") -> bytes:
    """The report as a JUnit XML document."""
    suite = ElementTree.Element(
        "testsuite",
        name=suite_name,
        tests=str(len(report.results) + len(report.not_run) + (report.cut_short_by is not None)),
        failures=str(report.count(Outcome.FAILED)),
        errors=str(report.count(Outcome.ABORTED) + (report.cut_short_by is not None)),
        skipped=str(report.count(Outcome.SKIPPED) + len(report.not_run)),
        time=f"{report.duration_s:.3f}",
    )
    properties = ElementTree.SubElement(suite, "properties")
    ElementTree.SubElement(properties, "property", name="target", value=report.target)
    if report.hint is not None:  # (what the failures suggest: the controller's algorithm)
        ElementTree.SubElement(properties, "property", name="hint", value=report.hint)
    for result in report.results:
        case = ElementTree.SubElement(
            suite,
            "testcase",
            classname="rovlink.check." + "_".join(result.rules),
            name=result.name,
            time=f"{result.duration_s:.3f}",
        )
        if result.outcome is Outcome.SKIPPED:
            ElementTree.SubElement(case, "skipped", message=result.message)
        elif result.failed:
            tag = "failure" if result.outcome is Outcome.FAILED else "error"
            element = ElementTree.SubElement(case, tag, message=result.message)
            element.text = evidence_text(result.evidence)
    if report.cut_short_by is not None:  # (an interrupted run is no pass: a case in error)
        case = ElementTree.SubElement(
            suite, "testcase", classname="rovlink.check", name="interrupted"
        )
        ElementTree.SubElement(case, "error", message=report.cut_short_by)
    # The checks an abort left out are there as skipped: a CI that counts the cases sees them.
    for name in report.not_run:
        case = ElementTree.SubElement(suite, "testcase", classname="rovlink.check", name=name)
        ElementTree.SubElement(case, "skipped", message=f"not run: {report.stopped_because}")
    ElementTree.indent(suite)
    document: bytes = ElementTree.tostring(suite, encoding="utf-8", xml_declaration=True)
    return document


def junit_not_started(target: str, why: str, suite_name: str = "rovlink check") -> bytes:
    """A JUnit XML document for a run that could not start (the link did not open, the
    controller did not answer, a leak was latched): one test case, ``preflight``, in error.
    Written in place of a report, so that a CI reads this run's failure, not the file an earlier
    run left."""
    suite = ElementTree.Element(
        "testsuite", name=suite_name, tests="1", failures="0", errors="1", skipped="0", time="0"
    )
    properties = ElementTree.SubElement(suite, "properties")
    ElementTree.SubElement(properties, "property", name="target", value=target)
    case = ElementTree.SubElement(suite, "testcase", classname="rovlink.check", name="preflight")
    ElementTree.SubElement(case, "error", message=why)
    ElementTree.indent(suite)
    document: bytes = ElementTree.tostring(suite, encoding="utf-8", xml_declaration=True)
    return document


def write_junit(report: Report, path: Path | str) -> None:
    """Write :func:`junit_xml` to ``path``."""
    Path(path).write_bytes(junit_xml(report) + b"\n")
