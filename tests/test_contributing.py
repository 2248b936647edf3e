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


#: Each file derived from the command table, with the command its own notice says regenerates it.
GENERATED = {
    "src/rovlink/client/command_methods.py": "python -m rovlink.client.method_table",
    "src/rovlink/aio/command_methods.py": "python -m rovlink.client.method_table",
    "docs/driver.md": "python -m rovlink.client.method_table",
    "docs/commands.md": "rovlink reference > docs/commands.md",
    "firmware/c/rovlink_commands.h": "python -m rovlink.protocol.c_table firmware/c",
    "firmware/c/rovlink_commands.c": "python -m rovlink.protocol.c_table firmware/c",
}


def _section(document: str, heading: str) -> str:
    text = (ROOT / document).read_text(encoding="utf-8")
    start = text.index(heading)
    end = text.find("\n#", start + len(heading))
    return text[start : end if end != -1 else len(text)]


def test_each_generated_file_names_the_command_that_makes_it() -> None:
    stale_notices = [
        path
        for path, command in GENERATED.items()
        if command not in " ".join((ROOT / path).read_text(encoding="utf-8").split())
    ]
    assert stale_notices == []


def test_a_new_command_regenerates_every_file_derived_from_the_command_table() -> None:
    sections = {
        "ARCHITECTURE.md": _section("ARCHITECTURE.md", "### A new command"),
        "CONTRIBUTING.md": _section("CONTRIBUTING.md", "## Generated files"),
    }
    # (docs/builders.md's table of checks, one a command, is checks_markdown()'s output.)
    commands = {*GENERATED.values(), "checks_markdown()"}
    unsaid = sorted(
        f"{document}: {command}"
        for document, section in sections.items()
        for command in commands
        if command not in section
    )
    assert unsaid == []
