"""Every ``>>>`` example in the package's docstrings runs as written."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import rovlink

# ``python -m rovlink`` runs the command line when imported.
_NOT_IMPORTED = {"rovlink.__main__"}

MODULES = sorted(
    info.name
    for info in pkgutil.walk_packages(rovlink.__path__, prefix="rovlink.")
    if info.name not in _NOT_IMPORTED
)


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.failed == 0


def test_the_pure_cores_have_examples() -> None:
    # The modules a reader starts from show how they are used, and the examples are checked.
    for name in (
        "rovlink.protocol",
        "rovlink.protocol.checksum",
        "rovlink.protocol.decoder",
        "rovlink.protocol.frames",
        "rovlink.client.command_text",
        "rovlink.piloting.commanded",
        "rovlink.monitor.compass",
    ):
        assert doctest.testmod(importlib.import_module(name)).attempted > 0, name
