"""One version source: the installed distribution's version is the package's ``__version__``."""

from __future__ import annotations

import importlib.metadata

import rovlink


def test_the_package_and_its_metadata_agree_on_the_version() -> None:
    assert rovlink.__version__ == importlib.metadata.version("rovlink")
