"""The layer rules of ARCHITECTURE.md are each enforced by an import-linter contract of
``pyproject.toml``: a package the rules forbid to a layer is in a contract of that layer, so
``lint-imports`` fails a new import that goes the wrong way (a contract that names some of the
tools but not the others lets an import of the rest through)."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "rovlink"

#: The tools (ARCHITECTURE.md, "The tools"), above the host driver.
TOOLS = {
    "console",
    "monitor",
    "piloting",
    "recorder",
    "bridges",
    "station",
    "conformance",
    "faults",
    "tuning",
}
#: What every layer may stand on (the logging policy, and the two helpers the controller's lines
#: and the host driver's links share), and the command line above everything.
SHARED = {"logs", "busy_tcp", "serial_latency"}
LAYERS = {"protocol", "controller", "sim", "board", "client", "aio", "cli"}

#: Per layer, what ARCHITECTURE.md says it never imports.
RULES: dict[str, set[str]] = {
    "protocol": (LAYERS | TOOLS | SHARED) - {"protocol"},
    "controller": {"client", "aio", "sim", "board", "cli"} | TOOLS,
    "sim": {"client", "aio", "board", "cli"} | TOOLS,
    "board": {"client", "aio", "sim", "cli"} | TOOLS,
    "client": {"controller", "sim", "board", "cli"} | TOOLS,
    "aio": {"controller", "sim", "board", "cli"} | TOOLS,
    **{tool: {"controller", "sim", "board", "cli"} for tool in TOOLS},
}


def _top_level_names() -> set[str]:
    names = {path.name for path in PACKAGE.iterdir() if (path / "__init__.py").is_file()}
    names |= {path.stem for path in PACKAGE.glob("*.py") if not path.stem.startswith("__")}
    return names


def _forbidden_by_contracts(source: str) -> set[str]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    forbidden: set[str] = set()
    for contract in config["tool"]["importlinter"]["contracts"]:
        assert contract["type"] == "forbidden"
        if f"rovlink.{source}" in contract["source_modules"]:
            forbidden |= {name.removeprefix("rovlink.") for name in contract["forbidden_modules"]}
    return forbidden


def test_every_package_has_a_place_in_the_layers() -> None:
    unplaced = _top_level_names() - LAYERS - TOOLS - SHARED
    assert unplaced == set(), "place it in ARCHITECTURE.md, its contracts and this test"


@pytest.mark.parametrize("source", sorted(RULES))
def test_a_contract_enforces_each_rule(source: str) -> None:
    missing = RULES[source] - _forbidden_by_contracts(source)
    assert missing == set(), f"rovlink.{source} is not forbidden these by pyproject.toml"


def _imports_below_the_client(path: Path) -> bool:
    below = ("rovlink.controller", "rovlink.sim", "rovlink.board")
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            names = [node.module or ""]
        elif isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        else:
            continue
        if any(name == layer or name.startswith(f"{layer}.") for name in names for layer in below):
            return True
    return False


def test_the_architecture_names_every_command_module_that_imports_below_the_client() -> None:
    text = (ROOT / "ARCHITECTURE.md").read_text(encoding="utf-8")
    start = text.index("- Above the client, only the command line imports")
    rule = text[start : text.index("\n- ", start)]
    importers = {
        f"cli/{path.name}"
        for path in sorted((PACKAGE / "cli").glob("*.py"))
        if _imports_below_the_client(path)
    }
    unnamed = {name for name in importers if f"`{name}`" not in rule}
    assert importers
    assert unnamed == set()
