"""The build stops at once, with the reason, on a Python that ``requires-python`` excludes.

pip before 24.0 checks a local project's ``requires-python`` only after resolving every other
requirement: on Python 3.9, whose venv brings pip 23.0, ``pip install '.[all]'`` spent minutes
downloading dependencies before it said anything. The metadata is prepared on the Python the
project is installed for, before any dependency is looked at.
"""

from __future__ import annotations

import platform
from typing import Any

from hatchling.metadata.plugin.interface import MetadataHookInterface
from packaging.specifiers import SpecifierSet


def refusal(requires_python: str, version: str) -> str | None:
    """Why the project cannot be installed for Python ``version``; None if it can."""
    if SpecifierSet(requires_python).contains(version):
        return None
    return f"rovlink needs Python {requires_python} (this is Python {version}): see README.md"


class RefuseUnsupportedPython(MetadataHookInterface):
    """Hatchling's hook, run as the metadata is prepared: it changes nothing."""

    PLUGIN_NAME = "custom"

    def update(self, metadata: dict[str, Any]) -> None:
        """Stop the build on a Python that ``requires-python`` excludes."""
        why = refusal(metadata["requires-python"], platform.python_version())
        if why is not None:
            raise SystemExit(why)
