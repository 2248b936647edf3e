"""The ready line's TCP endpoint, as a user copies it into a URL."""

from __future__ import annotations

import pytest

from rovlink.cli.tcp_endpoint import REMOTE_MARK, tcp_endpoint


def test_an_ipv6_endpoint_is_written_in_brackets() -> None:
    # Before, `rovlink sim --tcp [::1]:5760` said `tcp ::1:5760`, which no URL takes as it is.
    assert tcp_endpoint("::1", 5760, "rovlink.sim") == "tcp [::1]:5760"


def test_a_remote_ipv6_endpoint_is_written_in_brackets_and_warned_of(
    caplog: pytest.LogCaptureFixture,
) -> None:
    assert tcp_endpoint("::", 5760, "rovlink.sim") == f"tcp [::]:5760 {REMOTE_MARK}"
    assert "listening on [::]:5760 (every network interface)" in caplog.text
