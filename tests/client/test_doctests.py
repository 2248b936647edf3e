"""The examples in the driver's pure modules run as written."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = [
    "rovlink.client",
    "rovlink.client.command_text",
    "rovlink.client.counters",
    "rovlink.client.errors",
    "rovlink.client.links",
    "rovlink.client.operations",
    "rovlink.client.options",
    "rovlink.client.sensors",
    "rovlink.client.session",
    "rovlink.client.url",
]


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0
