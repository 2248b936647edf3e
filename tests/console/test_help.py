"""help lists every command of the table with its description; help NAME shows one in full."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rovlink.console.actions import parse_line
from rovlink.console.help import STOP_KEY_TEXT, command_help, overview
from rovlink.protocol import COMMANDS, Spec


def test_overview_lists_every_command_with_its_description() -> None:
    text = "\n".join(overview())
    for spec in COMMANDS:
        assert f"  {spec.name} " in text
        assert spec.description in text
    assert STOP_KEY_TEXT in text


@pytest.mark.parametrize("spec", COMMANDS, ids=lambda spec: spec.name)
def test_each_command_shows_its_arguments_and_ranges(spec: Spec) -> None:
    lines = command_help(spec.name)
    assert lines[0].split()[0] == spec.name
    text = "\n".join(lines)
    assert spec.template() in text
    for argument in spec.arguments:
        assert f"{argument.name}: {argument.range_text()}" in text
    assert ("motion: dropped" in text) is spec.motion


def test_th_in_full() -> None:
    assert command_help("th") == [
        "th <direction_deg 0–360> <power_percent 0–100>",
        "  horizontal motion: direction (0 ahead, clockwise) and power",
        "  frame: #th.<direction_deg>.<power_percent>!",
        "  direction_deg: 0–360, degrees clockwise from the bow",
        "  power_percent: 0–100, horizontal power, %",
        "  motion: dropped by the controller while motors are locked (send start)",
        "  protocol rules: P7, P11",
    ]


def test_queries_list_their_replies_and_aliases_are_named() -> None:
    assert "  replies: $qd, $qr, $q.l, $qro, $qpi, $qhe" in command_help("qsa")
    assert "  also spelled: mvpdd" in command_help("mvpidd")
    assert command_help("checksum")[0] == "checksum on|off"


def test_console_lines_the_docs_name_are_lines_the_console_takes() -> None:
    # Before, docs/tools.md and docs/team-setup.md told the reader to type `debug 1`, which the
    # console refuses ("unknown command 'debug'"): the command is debug1.
    docs = Path(__file__).resolve().parents[2] / "docs"
    quoted = [
        line
        for page in ("tools.md", "team-setup.md")
        for line in re.findall(r"the console's `([^`]+)`", (docs / page).read_text("utf-8"))
    ]
    assert quoted
    for line in quoted:
        assert parse_line(line) is not None, line
