"""The examples in the operator tools' plain modules run as written."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "rovlink.operator.commanded",
    "rovlink.operator.health",
    "rovlink.operator.readings",
    "rovlink.console.actions",
    "rovlink.console.completion",
    "rovlink.console.help",
    "rovlink.console.transcript",
    "rovlink.monitor.chart",
    "rovlink.monitor.compass",
    "rovlink.monitor.controls",
    "rovlink.monitor.readings",
]


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
