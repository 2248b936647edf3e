"""Every ``rovlink …`` command line shown in the README and ``docs/`` is one the command line
accepts: no option renamed or removed since the page was written, no value of the wrong kind.

The lines of ``sh`` and ``console`` blocks are read as a shell reads them (comments, quotes,
``\\`` continuations; in a ``console`` block only the lines after ``$``), each ``rovlink`` of a
pipeline or a list of commands separately, and parsed by the command's own parser. Nothing runs.
"""

from __future__ import annotations

import contextlib
import io
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

import pytest

from rovlink.cli import COMMANDS, build_parser

ROOT = Path(__file__).resolve().parents[2]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))

#: Where one command of a shell line ends and the next begins.
_SEPARATORS = frozenset({"|", "||", "&&", ";", "&"})


@dataclass(frozen=True)
class CommandLine:
    """One ``rovlink`` command of a page's shell example."""

    page: Path
    line: int
    words: tuple[str, ...]

    def __str__(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def _shell_lines(page: Path) -> list[tuple[int, str]]:
    """The shell lines of a page's ``sh`` and ``console`` blocks, continuations joined."""
    found: list[tuple[int, str]] = []
    kind: str | None = None
    pending: tuple[int, str] | None = None
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), start=1):
        stripped = line.strip()
        if stripped.startswith("```"):
            kind = stripped[3:] if kind is None else None
            continue
        if kind not in ("sh", "console"):
            continue
        if pending is not None:
            start, text = pending
            text = f"{text} {stripped}"
        elif kind == "console":
            if not stripped.startswith("$ "):
                continue  # (the command's output)
            start, text = number, stripped[2:]
        else:
            start, text = number, stripped
        if text.endswith("\\"):
            pending = (start, text[:-1])
            continue
        pending = None
        found.append((start, text))
    return found


def _command_lines() -> list[CommandLine]:
    found: list[CommandLine] = []
    for page in PAGES:
        for number, text in _shell_lines(page):
            lexer = shlex.shlex(text, posix=True, punctuation_chars=True)
            lexer.whitespace_split = True
            lexer.commenters = "#"
            words: list[str] = []
            for word in [*lexer, ";"]:
                if word in _SEPARATORS:
                    if words and words[0] == "rovlink":
                        found.append(CommandLine(page, number, tuple(words[1:])))
                    words = []
                elif not (not words and re.fullmatch(r"\w+=.*", word)):  # (VAR=value rovlink …)
                    words.append(word)
    return found


COMMAND_LINES = _command_lines()


def test_the_pages_show_command_lines_of_every_kind() -> None:
    # (A change to how lines are found must not make the test below check nothing.)
    shown = {line.words[0] for line in COMMAND_LINES if line.words}
    assert len(COMMAND_LINES) >= 40
    assert len(shown & set(COMMANDS)) >= 12, sorted(shown)


@pytest.mark.parametrize("command_line", COMMAND_LINES, ids=str)
def test_a_command_line_of_the_docs_is_accepted(command_line: CommandLine) -> None:
    words = list(command_line.words)
    command = next((word for word in words if word in COMMANDS), None)
    parser = build_parser(command)
    errors = io.StringIO()
    try:
        with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
            parser.parse_args(words)
    except SystemExit as ending:
        if ending.code not in (0, None):  # (--help and --version end with 0)
            shown = shlex.join(["rovlink", *words])
            pytest.fail(f"{command_line}: {shown}: {errors.getvalue().strip()}")


def _value_of(option: str, words: tuple[str, ...]) -> str | None:
    """The word after ``option`` in ``words``, if it is there."""
    return words[words.index(option) + 1] if option in words[:-1] else None


def test_a_replay_into_the_simulator_replays_a_dive_recorded_on_that_simulator() -> None:
    # Regression: recording.md recorded `rovlink demo --record dive.mcap` on a simulator of a
    # random seed and replayed it into 'sim://?seed=1': 120 of its 125 replies differed.
    replays = [
        line
        for line in COMMAND_LINES
        if line.words[:1] == ("replay",)
        and (_value_of("--to", line.words) or "").startswith("sim:")
    ]
    assert replays
    for replay in replays:
        url, recording = _value_of("--to", replay.words), replay.words[1]
        recorded_on = [
            line.words
            for line in COMMAND_LINES
            if line.page == replay.page
            and line.line < replay.line
            and _value_of("--record", line.words) == recording
        ]
        assert recorded_on, f"{replay}: no command line before it records {recording}"
        assert all(url in words for words in recorded_on), f"{replay}: {recorded_on} not on {url}"
