"""CONTRIBUTING.md's set-up says what CI installs: the Debian packages of
``.ci/debian-packages`` in its ``apt-get install`` line, and every test tool of the ``test``
extra by name (``-n 2`` needs pytest-xdist)."""

from __future__ import annotations

import re
import sys
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]


def _contributing() -> str:
    return (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8")


def test_the_apt_get_line_installs_every_debian_package_ci_installs() -> None:
    listed = ROOT.joinpath(".ci", "debian-packages").read_text(encoding="utf-8").splitlines()
    packages = {line.strip() for line in listed if line.strip() and not line.startswith("#")}
    lines = re.findall(r"^apt-get install (.+)$", _contributing(), flags=re.MULTILINE)
    assert len(lines) == 1
    assert set(lines[0].split()) == packages


def test_every_test_tool_is_named() -> None:
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    tools = [
        re.split(r"[<>=;\[ ]", requirement)[0]
        for requirement in extras["optional-dependencies"]["test"]
        if not requirement.startswith("rovlink")
    ]
    text = _contributing().lower()
    unnamed = [tool for tool in tools if tool.lower() not in text]
    assert tools
    assert unnamed == []
