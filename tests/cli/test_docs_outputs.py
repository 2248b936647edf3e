"""What the README and ``docs/`` show a command printing is what it prints.

In a ``console`` block, a line ``$ rovlink …`` and the lines of output after it are run as a
shell runs them (``rovlink`` being this Python's), when the command ends by itself and needs no
robot (``decode``, ``send`` to ``sim://``): its output must be the lines shown, ``…`` standing
for any text (the simulator's noisy sensors). A ``rovlink sim`` shown with its ready line is
started (on a free TCP port) and stopped once it has said it: the line must be the one shown,
but for what differs from run to run. Nothing else is run: the command lines of every block are
parsed in ``test_docs_command_lines.py``.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import threading
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))


@dataclass(frozen=True)
class ShownRun:
    """A command line of a page's ``console`` block and the output shown under it."""

    page: Path
    line: int
    command: str
    output: tuple[str, ...]

    def __str__(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def _shown_runs() -> list[ShownRun]:
    found: list[ShownRun] = []
    for page in PAGES:
        in_console = False
        current: tuple[int, str, list[str]] | None = None
        lines = page.read_text(encoding="utf-8").splitlines()
        for number, line in enumerate(lines, start=1):
            if line.strip().startswith("```"):
                if in_console and current is not None:
                    found.append(ShownRun(page, current[0], current[1], tuple(current[2])))
                current = None
                in_console = not in_console and line.strip() == "```console"
                continue
            if not in_console:
                continue
            if line.startswith("$ "):
                if current is not None:
                    found.append(ShownRun(page, current[0], current[1], tuple(current[2])))
                current = (number, line[2:], [])
            elif current is not None:
                current[2].append(line)
    return [run for run in found if run.output]


def _runs_alone(command: str) -> bool:
    """Whether ``command`` ends by itself and needs no robot: ``decode``, ``send sim://…``."""
    words = shlex.split(command, comments=True)
    start = words.index("rovlink") if "rovlink" in words else -1
    rovlink = words[start + 1 :] if start >= 0 else []
    if rovlink[:1] == ["decode"]:
        return True
    return rovlink[:1] == ["send"] and any(word.startswith("sim://") for word in rovlink)


SHOWN_RUNS = [run for run in _shown_runs() if _runs_alone(run.command)]


def test_the_pages_show_runs_to_check() -> None:
    # (A change to how blocks are read must not make the test below check nothing: the
    # README's decode, and driver.md's two sends.)
    assert len(SHOWN_RUNS) >= 3, [str(run) for run in SHOWN_RUNS]


@pytest.mark.integration
@pytest.mark.parametrize("shown", SHOWN_RUNS, ids=str)
def test_a_command_prints_what_the_page_shows(shown: ShownRun) -> None:
    script = f'rovlink() {{ "{sys.executable}" -m rovlink "$@"; }}\n{shown.command}\n'
    result = subprocess.run(
        ["bash", "-c", script], capture_output=True, text=True, check=False, timeout=60
    )
    assert (result.returncode, result.stderr) == (0, ""), f"{shown}: {shown.command}"
    expected = "\n".join(shown.output)
    pattern = ".*".join(re.escape(part) for part in expected.split("…"))
    assert re.fullmatch(pattern, result.stdout.rstrip("\n")), (
        f"{shown}: {shown.command} printed:\n{result.stdout}"
    )


# -- a server's ready line ---------------------------------------------------------------------

#: What differs from run to run in a ready line: the pseudo-terminal's path, a random seed, and
#: the TCP port (each run takes a free one, not the page's).
_VARYING = (
    (re.compile(r"/dev/pts/\d+"), "/dev/pts/…"),
    (re.compile(r"seed \d+"), "seed …"),
    (re.compile(r"(tcp [\d.]+):\d+"), r"\1:…"),
)


def _serves(run: ShownRun) -> bool:
    """Whether ``run`` starts ``rovlink sim``, which serves until it is stopped."""
    return shlex.split(run.command, comments=True)[:2] == ["rovlink", "sim"]


def _on_a_free_port(words: list[str]) -> list[str]:
    """``words`` with the port of ``--tcp [HOST:]PORT`` made 0: any free one."""
    return [
        re.sub(r"\d+$", "0", word) if index and words[index - 1] == "--tcp" else word
        for index, word in enumerate(words)
    ]


SERVING_RUNS = [run for run in _shown_runs() if _serves(run)]


def test_the_pages_show_ready_lines_to_check() -> None:
    # (The README's, controller.md's and driver.md's `rovlink sim`.)
    assert len(SERVING_RUNS) >= 3, [str(run) for run in SERVING_RUNS]


@pytest.mark.integration
@pytest.mark.parametrize("shown", SERVING_RUNS, ids=str)
def test_a_server_says_ready_as_the_page_shows(shown: ShownRun) -> None:
    words = _on_a_free_port(shlex.split(shown.command, comments=True)[1:])
    server = subprocess.Popen(
        [sys.executable, "-m", "rovlink", *words],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    gives_up = threading.Timer(30.0, server.kill)  # (a server that never says it is ready)
    gives_up.start()
    try:
        assert server.stdout is not None
        ready = server.stdout.readline().rstrip("\n")  # (it ends when the server does)
    finally:
        gives_up.cancel()
        server.terminate()
        server.communicate(timeout=30)
    expected = shown.output[0]
    for varying, any_text in _VARYING:
        expected = varying.sub(any_text, expected)
    pattern = ".*".join(re.escape(part) for part in expected.split("…"))
    assert re.fullmatch(pattern, ready), f"{shown}: {shown.command} printed {ready!r}"
