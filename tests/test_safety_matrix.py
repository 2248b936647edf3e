"""The safety matrix of ``docs/team-setup.md`` (*When something dies*) cites tests: each must
exist, so that the table a user trusts cannot name a test that was renamed or removed, and each
row must cite one or say why none is needed (*by design*)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]
_DOC = _ROOT / "docs" / "team-setup.md"
_CITED = re.compile(r"`(tests/[\w/]+\.py)::(test_\w+)`")


def _section() -> str:
    text = _DOC.read_text(encoding="utf-8")
    start = text.index("\n## When something dies\n")
    end = text.find("\n## ", start + 1)
    return text[start : end if end >= 0 else len(text)]


def _tests_in(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    return {
        node.name
        for node in ast.walk(tree)
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))
        and node.name.startswith("test_")
    }


def test_every_test_the_safety_matrix_cites_exists() -> None:
    cited = _CITED.findall(_section())
    assert len(cited) >= 50  # (the section was found, and its tests read)
    missing = [
        f"{path}::{name}"
        for path, name in cited
        if not (_ROOT / path).is_file() or name not in _tests_in(_ROOT / path)
    ]
    assert missing == []


def test_every_row_of_the_safety_matrix_cites_a_test_or_says_why_not() -> None:
    rows = [
        line
        for line in _section().splitlines()
        if line.startswith("| ")
        and not line.startswith("| what |")
        and not line.startswith("| tool |")
    ]
    assert len(rows) >= 30
    bare = [row for row in rows if not _CITED.search(row) and "by design" not in row]
    assert bare == []
