"""``rovlink check``: a conformance suite for any controller of the protocol, on any link.

Every command of PROTOCOL.md and every decision a host can observe gets a named check; each
failure carries the bytes sent and received. The checks derive names, arguments and ranges from
the command table.

Example::

    from rovlink.client.links import open_link
    from rovlink.client.url import parse_url
    from rovlink.conformance import run_checks

    report = run_checks(open_link(parse_url("sim://")), "sim://")
    print(report.passed, [result.name for result in report.failures])
"""

from rovlink.conformance.junit import junit_xml, write_junit
from rovlink.conformance.registry import CHECKS, Check, SuiteOptions, checks_markdown
from rovlink.conformance.results import CheckResult, Outcome, Report
from rovlink.conformance.runner import PreflightError, run_checks, select_checks

__all__ = [
    "CHECKS",
    "Check",
    "CheckResult",
    "Outcome",
    "PreflightError",
    "Report",
    "SuiteOptions",
    "checks_markdown",
    "junit_xml",
    "run_checks",
    "select_checks",
    "write_junit",
]
