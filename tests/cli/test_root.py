"""The ``rovlink`` command itself: its version, its help, and what it imports to start."""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

import rovlink
from rovlink.cli import COMMANDS as ALL_COMMANDS
from rovlink.cli import build_parser
from tests.cli.closed_pipe import run_into_a_closed_pipe
from tests.cli.conftest import RunCli

COMMANDS = ("decode", "reference", "sim", "send", "demo", "console", "monitor")


def test_version(run_cli: RunCli) -> None:
    result = run_cli("--version")
    assert result.status == 0
    assert result.out.strip() == f"rovlink {rovlink.__version__}"


# The help asked for before a command's name lists every command too (main builds only the named
# command's parser when the name comes first).
@pytest.mark.parametrize("words", [("--help",), ("--help", "decode"), ("-v", "-h", "send")])
def test_help_lists_every_command(run_cli: RunCli, words: tuple[str, ...]) -> None:
    result = run_cli(*words)
    assert result.status == 0
    for name in COMMANDS:
        assert f"    {name} " in result.out
    assert "examples:" in result.out


def test_no_arguments_prints_the_help(run_cli: RunCli) -> None:
    result = run_cli()
    assert result.status == 0
    assert result.out.startswith("usage: rovlink")
    assert "commands:" in result.out


def test_every_command_has_a_description_and_option_help(run_cli: RunCli) -> None:
    for name in COMMANDS:
        result = run_cli(name, "--help")
        assert result.status == 0, name
        assert result.out.startswith(f"usage: rovlink {name}")
        description = result.out.split("\n\n")[1]
        assert len(description) > 20, name


@pytest.mark.parametrize("name", ALL_COMMANDS)
def test_every_commands_help_ends_with_examples(run_cli: RunCli, name: str) -> None:
    # As docs/tools.md says of `rovlink COMMAND --help`; `reference` had none.
    result = run_cli(name, "--help")
    examples = result.out.split("\nexamples:\n", 1)[-1] if "\nexamples:\n" in result.out else ""
    assert f"  rovlink {name}" in examples


def _help_examples() -> list[tuple[str, list[str]]]:
    """The ``rovlink …`` lines of every help's examples: (the help's command, the words)."""
    from rovlink.cli import _EPILOG

    found: list[tuple[str, list[str]]] = []
    for name in ["rovlink", *ALL_COMMANDS]:
        epilog = _EPILOG if name == "rovlink" else _command_parser(name).epilog or ""
        for line in epilog.replace("\\\n", " ").splitlines():
            if line.strip().startswith("rovlink "):
                example = re.split(r"\s{2,}", line.strip())[0]  # (the words after it explain)
                lexer = shlex.shlex(example, posix=True, punctuation_chars=True)
                lexer.whitespace_split = True
                words = list(lexer)
                ends = [words.index(word) for word in ("|", ">") if word in words]
                found.append((name, words[1 : min(ends, default=len(words))]))
    return found


def test_the_help_examples_are_command_lines_the_commands_accept() -> None:
    # The pages' examples are parsed in test_docs_command_lines.py; those of --help were not.
    examples = _help_examples()
    assert len(examples) >= 2 * len(ALL_COMMANDS)
    refused = []
    for name, words in examples:
        parser = build_parser(next((word for word in words if word in ALL_COMMANDS), None))
        errors = io.StringIO()
        try:
            with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
                parser.parse_args(words)
        except SystemExit as ending:
            if ending.code not in (0, None):
                refused.append(f"{name}: {shlex.join(words)}: {errors.getvalue().strip()}")
    assert not refused


def test_the_help_examples_quote_what_a_shell_would_expand() -> None:
    # `rovlink tune sim://?preset=heavy` is a glob: zsh refuses it ("no matches found"), and a
    # file that matched would replace it in bash. The docs quoted it; tune's --help did not.
    from rovlink.cli import _EPILOG

    unquoted = []
    for name in ["rovlink", *ALL_COMMANDS]:
        epilog = _EPILOG if name == "rovlink" else _command_parser(name).epilog or ""
        for line in epilog.replace("\\\n", " ").splitlines():
            if line.strip().startswith("rovlink "):
                example = re.split(r"\s{2,}", line.strip())[0]
                for word in shlex.split(example, posix=False):  # (quotes kept)
                    if re.search(r"[?*\[]", word) and word[0] not in "'\"":
                        unquoted.append(f"{name}: {word}")
    assert not unquoted


@pytest.mark.parametrize("name", [None, *ALL_COMMANDS])
def test_help_is_plain_text_without_markup(run_cli: RunCli, name: str | None) -> None:
    # Regression: descriptions came from docstrings with their Sphinx markup (:func:`…`, ``…``).
    result = run_cli(*([name] if name else []), "--help")
    assert result.status == 0
    assert "`" not in result.out
    assert not re.search(r":[a-z]+:", result.out.replace("examples:", ""))


def test_on_off_flags_take_no_value(run_cli: RunCli) -> None:
    result = run_cli("send", "--help")
    assert "--checksum, --no-checksum" in result.out
    assert "(default: off)" in result.out
    assert "--timeout SECONDS" in result.out
    # "true" is not swallowed as the URL: it is an extra argument, a usage error.
    result = run_cli("demo", "--checksum", "true", "sim://")
    assert result.status == 2
    assert "unrecognized arguments: sim://" in result.err
    assert "could not open" not in result.err


def _command_parser(name: str) -> argparse.ArgumentParser:
    parser = build_parser(name, others=False)
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    command_parser: argparse.ArgumentParser = commands.choices[name]
    return command_parser


def _shown_options() -> list[tuple[str, str, str, str]]:
    """Every option of every command as its help shows it: (command, option, what it takes,
    its help)."""
    shown: list[tuple[str, str, str, str]] = []
    for name in ALL_COMMANDS:
        parser = _command_parser(name)
        formatter = parser._get_formatter()
        for action in parser._actions:
            if action.help in (None, argparse.SUPPRESS):
                continue
            if not action.option_strings:
                takes = formatter._format_args(action, action.dest)
                unnamed = " <its variable's name>" if action.metavar is None else ""
                help_text = formatter._expand_help(action) + unnamed
                shown.append((name, action.dest, takes.strip("[]"), help_text))
                continue
            takes = "" if action.nargs == 0 else formatter._format_args(action, action.dest.upper())
            default = action.default
            stated = default is None or default is False or default in ([], argparse.SUPPRESS)
            stated = stated or action.nargs == 0
            help_text = formatter._expand_help(action) + ("" if stated else " <no default>")
            shown.append((name, action.option_strings[-1], takes, help_text))
    return shown


def test_every_option_names_what_it_takes_and_states_its_default() -> None:
    # Before, some said "--min-counts MIN_COUNTS" or "--step-from STEP_FROM" (argparse's name
    # of the variable) where a unit or kind belongs, `check [url]` where the rest say `URL`,
    # and "(default 20)" or no default at all where the rest say "(default: 20)".
    problems = [
        f"rovlink {name} {option} {takes}: {help_text}"
        for name, option, takes, help_text in _shown_options()
        if "_" in takes
        or "<its variable's name>" in help_text
        or ("<no default>" in help_text and "(default: " not in help_text)
    ]
    assert not problems, "\n".join(problems)


#: Options that take a different thing in different commands, under the one name.
_NAMES_OF_TWO_MEANINGS = {"--output": "a recording or an image", "--port": "a device or a TCP port"}


def test_an_option_takes_the_same_kind_of_value_in_every_command() -> None:
    # Before, `tune --depth DEPTH` where `demo` and `calibrate` say `--depth CM`, and
    # `check --algorithm ALGORITHM` where every other command says `--algorithm NAME`.
    takes_by_option: dict[str, set[str]] = {}
    for _, option, takes, _ in _shown_options():
        if option not in _NAMES_OF_TWO_MEANINGS:
            takes_by_option.setdefault(option, set()).add(takes)
    differing = {option: takes for option, takes in takes_by_option.items() if len(takes) > 1}
    assert not differing


def test_unknown_command(run_cli: RunCli) -> None:
    result = run_cli("fly")
    assert result.status == 2
    assert "invalid choice: 'fly'" in result.err


@pytest.mark.integration
def test_version_imports_neither_the_driver_nor_pyserial_nor_rich() -> None:
    code = (
        "import sys\n"
        "from rovlink.cli import main\n"
        "assert main(['--version']) == 0\n"
        "heavy = [name for name in sys.modules if name.split('.')[0] in "
        "('serial', 'rich', 'textual', 'prompt_toolkit')"
        " or name.startswith('rovlink.client')]\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=30)


@pytest.mark.integration
def test_decode_imports_no_driver() -> None:
    code = (
        "import sys\n"
        "from rovlink.cli import main\n"
        "sys.argv = ['rovlink', 'decode', '--stats', '-']\n"
        "assert main(sys.argv[1:]) == 0\n"
        "heavy = [name for name in sys.modules if name.split('.')[0] in "
        "('serial', 'rich', 'textual', 'prompt_toolkit') or name.startswith('rovlink.client')]\n"
        "assert not heavy, heavy\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=30, input=b"#qd!")


@pytest.mark.integration
def test_decode_imports_no_module_it_does_not_need() -> None:
    # Each of these costs as much as the rest of decode's start-up together: dataclasses
    # (with inspect and ast) and typing. Those the interpreter loaded itself (a .pth file
    # may) are not the command's.
    code = (
        "import sys\n"
        "before = set(sys.modules)\n"
        "from rovlink.cli import main\n"
        "assert main(['decode', '-']) == 0\n"
        "loaded = [name for name in ('dataclasses', 'inspect', 'ast', 'typing', 'contextlib')"
        " if name in sys.modules and name not in before]\n"
        "assert not loaded, loaded\n"
    )
    subprocess.run(
        [sys.executable, "-c", code],
        check=True,
        timeout=30,
        input=b"boot\r\n#qsa!$qd.57!$qr.134!#crcon!#qd8C!",
        stdout=subprocess.DEVNULL,
    )


@pytest.mark.integration
def test_help_imports_no_module_only_running_needs() -> None:
    # `rovlink calibrate --help` imported statistics (with decimal, fractions and random), a
    # sixth of its start-up, for the mean of the readings it takes when it runs.
    code = (
        "import contextlib, io, sys\n"
        "from rovlink.cli import COMMANDS, main\n"
        "heavy = {'serial', 'rich', 'textual', 'prompt_toolkit', 'matplotlib', 'numpy',\n"
        "         'aiomqtt', 'paho', 'pymavlink', 'starlette', 'uvicorn', 'mcap', 'asyncio',\n"
        "         'ssl', 'statistics', 'decimal', 'random'}\n"
        "loaded = {}\n"
        "for name in COMMANDS:\n"
        "    before = set(sys.modules)\n"
        "    with contextlib.redirect_stdout(io.StringIO()):\n"
        "        assert main([name, '--help']) == 0\n"
        "    new = {module.split('.')[0] for module in set(sys.modules) - before} & heavy\n"
        "    if new:\n"
        "        loaded[name] = sorted(new)\n"
        "assert not loaded, loaded\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=False, timeout=60
    )
    assert result.returncode == 0, result.stderr.splitlines()[-1:]


@pytest.mark.integration
@pytest.mark.parametrize(
    ("words", "said"),
    [
        (
            [b"decode", b"\xff-missing.bin"],
            b"rovlink decode: cannot read \\xff-missing.bin: No such file or directory\n",
        ),
        (
            [b"send", b"sim://", b"q\xffd"],
            b"rovlink send: error: command 1 ('q\\xffd'): unknown command 'q\\xffd'; did you "
            b"mean qd?\n",
        ),
    ],
    ids=["failure", "usage error"],
)
def test_a_word_that_is_not_utf8_is_said_with_its_bytes(
    words: list[bytes], said: bytes, tmp_path: Path
) -> None:
    # A file name from a FAT stick or an old system. Before, "\udcff-missing.bin": Python's
    # stand-in for the byte, which no name holds.
    result = subprocess.run(
        [sys.executable.encode(), b"-m", b"rovlink", *words],
        capture_output=True,
        check=False,
        timeout=60,
        cwd=tmp_path,
    )
    assert result.stderr.splitlines(keepends=True)[-1] == said


@pytest.mark.integration
def test_output_to_a_full_device_is_a_one_line_error() -> None:
    with open("/dev/full", "wb") as full:
        result = subprocess.run(
            [sys.executable, "-m", "rovlink", "reference"],
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
            check=False,
            timeout=60,
        )
    assert result.returncode == 1
    assert result.stderr == "rovlink reference: cannot write the output: No space left on device\n"


@pytest.mark.integration
def test_output_to_a_closed_pipe_ends_quietly() -> None:
    """``rovlink reference | head -0``: the reader is gone before the first write."""
    result = run_into_a_closed_pipe("reference")
    assert (result.returncode, result.stderr) == (0, "")


@pytest.mark.integration
@pytest.mark.parametrize(
    "words",
    [("check", "--list"), ("demo", "--depth", "5", "--hold", "0", "--leg", "0")],
    ids=["check", "demo"],
)
def test_a_table_to_a_closed_pipe_ends_quietly(words: tuple[str, ...]) -> None:
    # Before, rich's console ended these with status 1 and nothing said (`check --list | head`
    # read as a failed check).
    result = run_into_a_closed_pipe(*words)
    assert (result.returncode, result.stderr) == (0, "")


def test_an_unknown_option_is_said_by_the_commands_own_parser(
    run_cli: RunCli, tmp_path: Path
) -> None:
    # Before, the root parser said it ("rovlink: error: …") after its own usage line, which
    # names neither the command nor its options (plot's -o given to replay, as here).
    result = run_cli("replay", str(tmp_path / "dive.mcap"), "-o", "dive.png")
    assert result.status == 2
    lines = result.err.splitlines()
    assert lines[0].startswith("usage: rovlink replay ")
    assert lines[-1] == "rovlink replay: error: unrecognized arguments: -o dive.png"
    result = run_cli("--bogus")
    assert result.status == 2
    assert result.err.splitlines()[-1] == "rovlink: error: unrecognized arguments: --bogus"


def test_reference_writes_the_docs_page_whatever_the_output_s_encoding(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch
) -> None:
    # `rovlink reference > docs/commands.md` under a locale that is not UTF-8 (or on a Windows
    # console): the page is UTF-8 Markdown, byte for byte docs/commands.md, not a traceback.
    output = io.BytesIO()
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(output, encoding="ascii"))
    result = run_cli("reference")
    assert (result.status, result.err) == (0, "")
    sys.stdout.flush()
    docs = Path(__file__).resolve().parents[2] / "docs" / "commands.md"
    assert output.getvalue() == docs.read_bytes()
