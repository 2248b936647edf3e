"""docs/commands.md is generated from the command table and must be current."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rovlink.protocol import COMMANDS, RESPONSES, Decoder, Frame, Spec, reference
from rovlink.protocol.reference import command_reference_markdown

DOCS = Path(__file__).resolve().parents[2] / "docs" / "commands.md"
PROTOCOL = Path(__file__).resolve().parents[2] / "PROTOCOL.md"


def test_docs_command_reference_is_current() -> None:
    assert DOCS.read_text(encoding="utf-8") == command_reference_markdown(), (
        "docs/commands.md is stale: run `rovlink reference > docs/commands.md`"
    )


def test_every_command_and_response_is_documented_with_a_decodable_example() -> None:
    text = command_reference_markdown()
    for spec in (*COMMANDS, *RESPONSES):
        row = next(
            line
            for line in text.splitlines()
            if line.startswith(f"| `{spec.name}` |") and f"`{spec.template()}`" in line
        )
        examples = [cell.strip().strip("`") for cell in row.split("|")[5:7]]
        for index, example in enumerate(examples):
            checksum_enabled = index == 1 and not spec.exact_match
            (event,) = Decoder(checksum_enabled=checksum_enabled).feed(example.encode())
            assert isinstance(event, Frame), (example, event)
            assert event.message.name == spec.name


def test_the_rules_the_reference_names_are_the_protocol_s() -> None:
    # The page said "Rules (P1…P19)" while PROTOCOL.md's Part 2 went on to P23.
    rules = re.findall(r"^\*\*P(\d+) ", PROTOCOL.read_text(encoding="utf-8"), re.MULTILINE)
    assert rules == [str(number) for number in range(1, len(rules) + 1)]
    text = command_reference_markdown()
    assert set(re.findall(r"\bP(\d+)\b", text)) <= set(rules)
    for last in re.findall(r"\bP1…P(\d+)\b", text):
        assert last == rules[-1]


def _with(spec: Spec, **changes: object) -> Spec:
    fields = {name: getattr(spec, name) for name in Spec.__match_args__}
    return Spec(**{**fields, **changes})


def test_the_frames_without_a_checksum_are_the_table_s(monkeypatch: pytest.MonkeyPatch) -> None:
    # Which frames go bare in checksum mode is said once, in the table (exact_match,
    # honoured_bare), not again by name in the page.
    table = tuple(
        _with(spec, honoured_bare=spec.name == "start", exact_match=spec.name == "crcon")
        for spec in COMMANDS
    )
    monkeypatch.setattr(reference, "COMMANDS", table)
    text = reference.command_reference_markdown()
    assert "every frame but `#crcon!` and the bare `#start!` carries" in text
    assert "bare `#start!` honoured in checksum mode" in text
    assert "bare `#stop!`" not in text
