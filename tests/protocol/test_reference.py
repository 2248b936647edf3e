"""docs/commands.md is generated from the command table and must be current."""

from __future__ import annotations

from pathlib import Path

from rovlink.protocol import COMMANDS, RESPONSES, Decoder, Frame
from rovlink.protocol.reference import command_reference_markdown

DOCS = Path(__file__).resolve().parents[2] / "docs" / "commands.md"


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
