"""The Python examples of the README and of ``docs/`` run as written, and show what they say.

A program runs against the simulator in place of the serial port it names. The frames its
comments name (``rov.move(0, 40)   # #th.0.40!``) must be among the frames it sent, and what a
comment says it prints (``# prints "…"``) must be printed; a ```` ```text ```` block right after a
program is all that it prints. A ``>>>`` example must give the value
or the error shown, ``…`` standing for any text; a statement whose comment names a condition of
:data:`CONDITIONS` ("the controller does not answer") runs against a controller in that state.
A block that is not a program (a signature) is marked ``<!-- not run: why -->`` on the line
before it.
"""

from __future__ import annotations

import ast
import contextlib
import io
import os
import re
import threading
import tokenize
import tty
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

import rovlink
from rovlink.client import Client
from rovlink.client.events import BytesSent, ClientEvent
from rovlink.protocol import encode
from tests.client.fake_controller import FakeController

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")))
NOT_RUN = "<!-- not run:"

#: The simulator in place of a serial port.
SIMULATOR = "sim://"
PORT = '"/dev/ttyUSB0"'
#: A program's checksum algorithm, which the simulator is then configured for.
_ALGORITHM = re.compile(r'algorithm="(\w+)"')

#: A frame named in a comment, and what a comment says is printed.
_FRAME = re.compile(r"#[^\s#!]+!")
_PRINTS = re.compile(r'prints "([^"]*)"')


@dataclass(frozen=True)
class Example:
    """One ```` ```python ```` block: where it is and its code."""

    page: Path
    line: int
    code: str
    #: The ```` ```text ```` block that follows a program: what it prints.
    output: str | None = None

    def __str__(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    @property
    def is_session(self) -> bool:
        """Whether it is an interactive session (``>>>``) rather than a program."""
        return self.code.lstrip().startswith(">>>")


def _output_after(lines: list[str], index: int) -> str | None:
    """The ```` ```text ```` block at ``lines[index]`` (after blank lines), if there is one."""
    while index < len(lines) and not lines[index].strip():
        index += 1
    if index == len(lines) or lines[index].strip() != "```text":
        return None
    end = next(i for i in range(index + 1, len(lines)) if lines[i].strip() == "```")
    return "\n".join(lines[index + 1 : end])


def _examples() -> list[Example]:
    found: list[Example] = []
    for page in PAGES:
        lines = page.read_text(encoding="utf-8").splitlines()
        index = 0
        while index < len(lines):
            if lines[index].strip() == "```python":
                start = index + 1
                end = next(i for i in range(start, len(lines)) if lines[i].strip() == "```")
                marked = index > 0 and lines[index - 1].strip().startswith(NOT_RUN)
                if not marked:
                    code = "\n".join(lines[start:end])
                    found.append(Example(page, start + 1, code, _output_after(lines, end + 1)))
                index = end
            index += 1
    return found


EXAMPLES = _examples()
PROGRAMS = [example for example in EXAMPLES if not example.is_session]
SESSIONS = [example for example in EXAMPLES if example.is_session]


def _on_the_simulator(code: str, config_dir: Path) -> str:
    """A program with the simulator in place of its serial port, set up for the checksum
    algorithm the line that opens it asks for (a team's firmware)."""
    lines: list[str] = []
    for line in code.splitlines():
        url = SIMULATOR
        algorithm = _ALGORITHM.search(line)
        if algorithm:
            config = config_dir / f"{algorithm.group(1)}.toml"
            config.write_text(f'[controller]\nchecksum_algorithm = "{algorithm.group(1)}"\n')
            url = f"sim://?config={config}"
        lines.append(line.replace(PORT, f'"{url}"'))
    return "\n".join(lines)


def _comments(code: str) -> list[str]:
    """The comments of a program, without their ``#``."""
    tokens = tokenize.generate_tokens(io.StringIO(code).readline)
    return [token.string[1:].strip() for token in tokens if token.type == tokenize.COMMENT]


def _pattern(shown: str) -> re.Pattern[str]:
    """What an example shows, ``…`` standing for any text."""
    return re.compile(".*".join(re.escape(part) for part in shown.split("…")), re.DOTALL)


class _FramesSent:
    """Every command written by any client an example makes, as a frame without checksum."""

    def __init__(self) -> None:
        self.frames: list[str] = []
        self._lock = threading.Lock()

    def __call__(self, event: ClientEvent) -> None:
        if isinstance(event, BytesSent) and event.command is not None:
            with self._lock:
                self.frames.append(encode(event.command).decode())


@pytest.fixture
def frames_sent(monkeypatch: pytest.MonkeyPatch) -> _FramesSent:
    """Have every ``rovlink.connect`` of an example report the frames it sends."""
    sent = _FramesSent()
    connect = rovlink.connect

    def connect_and_watch(*args: Any, **kwargs: Any) -> Client:
        client = connect(*args, **kwargs)
        client.subscribe(sent)
        return client

    monkeypatch.setattr(rovlink, "connect", connect_and_watch)
    return sent


def test_the_pages_have_examples_of_both_kinds() -> None:
    # (A change to how blocks are found must not make this test check nothing.)
    assert len(PROGRAMS) >= 8
    assert len(SESSIONS) >= 2


@pytest.mark.parametrize("example", PROGRAMS, ids=str)
def test_a_program_runs_and_sends_the_frames_its_comments_name(
    example: Example, frames_sent: _FramesSent, tmp_path: Path
) -> None:
    code = _on_the_simulator(example.code, tmp_path)
    printed = io.StringIO()
    threads_before = set(threading.enumerate())
    with rovlink.connect(SIMULATOR) as rov:  # for a fragment that uses one
        namespace: dict[str, object] = {
            "__name__": "__example__",
            "rovlink": rovlink,  # (a fragment imports nothing)
            "rov": rov,
            "log": io.StringIO(),
        }
        with contextlib.redirect_stdout(printed):
            exec(compile(code, str(example), "exec"), namespace)
            for thread in set(threading.enumerate()) - threads_before:
                if not thread.daemon:  # (a thread of the example's own)
                    thread.join(10.0)
                    assert not thread.is_alive(), f"{example}: {thread.name} did not end"
    comments = _comments(example.code)
    for comment in comments:
        # (A comment that begins with a frame names one sent: "# #th.0.40!  ahead at 40 %".)
        for frame in _FRAME.findall(comment) if comment.startswith("#") else ():
            assert frame in frames_sent.frames, f"{example}: {frame} not sent ({comment!r})"
        for text in _PRINTS.findall(comment):
            assert text in printed.getvalue(), f"{example}: did not print {text!r}"
    if example.output is not None:
        got = printed.getvalue().strip()
        assert _pattern(example.output.strip()).fullmatch(got), f"{example} printed {got!r}"


# -- sessions ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Condition:
    """A client on a controller in a state an example's comment names, and how what it says
    differs from the example's words on this machine."""

    client: Client
    replacements: dict[str, str]


@contextlib.contextmanager
def _on_a_pseudo_terminal(state: Callable[[FakeController], None]) -> Iterator[Condition]:
    """A client on a serial port (a pseudo-terminal) whose controller is put in a ``state``."""
    controller_end, terminal = os.openpty()
    tty.setraw(terminal)
    name = os.ttyname(terminal)
    fake = FakeController(controller_end)
    try:
        with rovlink.connect(name, keepalive=None) as client:
            state(fake)
            # (A pseudo-terminal whose other side closed reads as its end, as an unplugged
            # adapter does, or, a moment later, as an I/O error.)
            yield Condition(client, {"/dev/ttyUSB0": name, "device disconnected": "…"})
    finally:
        fake.close()
        os.close(terminal)


def _silent(fake: FakeController) -> None:
    fake.then(*["drop"] * 100)


def _unplugged(fake: FakeController) -> None:
    fake.close()


#: The conditions a statement's comment may name.
CONDITIONS: dict[str, Callable[[FakeController], None]] = {
    "the controller does not answer": _silent,
    "the USB adapter was unplugged": _unplugged,
}


def _statements(code: str) -> list[tuple[str, str]]:
    """The ``>>>`` statements of a session and what each shows."""
    statements: list[tuple[str, list[str]]] = []
    for line in code.splitlines():
        if line.startswith(">>> "):
            statements.append((line[4:], []))
        elif line.startswith("... ") and statements:
            source, shown = statements[-1]
            statements[-1] = (f"{source}\n{line[4:]}", shown)
        elif statements:
            statements[-1][1].append(line)
    return [(source, "\n".join(shown).strip()) for source, shown in statements]


def _run(source: str, namespace: dict[str, object]) -> str:
    """Run one statement as the interpreter would; what it shows (the value's repr, or the
    error as ``Name: message``)."""
    tree = ast.parse(source, mode="exec")
    try:
        if len(tree.body) == 1 and isinstance(tree.body[0], ast.Expr):
            value = eval(
                compile(ast.Expression(tree.body[0].value), "<example>", "eval"), namespace
            )
            return "" if value is None else repr(value)
        exec(compile(tree, "<example>", "exec"), namespace)
    except Exception as error:  # (what the example shows)
        return f"{type(error).__name__}: {error}"
    return ""


def _session_param(example: Example) -> Any:
    """A session as a test case: one whose comment names a condition runs on a real
    pseudo-terminal, so it is marked ``integration``."""
    on_a_terminal = any(
        source.partition("  # ")[2].strip() in CONDITIONS
        for source, _shown in _statements(example.code)
    )
    return pytest.param(example, marks=[pytest.mark.integration] if on_a_terminal else [])


@pytest.mark.parametrize("example", [_session_param(example) for example in SESSIONS], ids=str)
def test_a_session_shows_what_it_says(example: Example) -> None:
    with rovlink.connect(SIMULATOR) as rov:
        namespace: dict[str, object] = {"rov": rov}
        for source, shown in _statements(example.code):
            comment = source.partition("  # ")[2].strip()
            condition = CONDITIONS.get(comment)
            if condition is None:
                got = _run(source, namespace)
                replacements: dict[str, str] = {}
            else:
                with _on_a_pseudo_terminal(condition) as state:
                    got = _run(source, {**namespace, "rov": state.client})
                    replacements = state.replacements
            expected = shown
            for words, here in replacements.items():
                expected = expected.replace(words, here)
            assert _pattern(expected).fullmatch(got), f"{example}: {source!r} gave {got!r}"
