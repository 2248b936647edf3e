"""An extra's library that is missing is said with the line that installs it; one that is
installed but fails as it is imported is said as such (installing again would change nothing)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from rovlink.cli.extras import needs_extra
from tests.cli.conftest import RunCli
from tests.rovlink_process import rovlink_command, rovlink_environment

#: A command line of each command under test, the library it imports and its extra.
COMMANDS = [
    pytest.param(("plot", "dive.jsonl", "-o", "dive.png"), "matplotlib", "plot", id="plot"),
    pytest.param(
        ("mqtt", "sim://", "--robot", "r1", "--broker", "mqtt://127.0.0.1:1"),
        "aiomqtt",
        "mqtt",
        id="mqtt",
    ),
    pytest.param(("mavlink", "sim://"), "pymavlink", "mavlink", id="mavlink"),
]

_BROKEN = 'raise ImportError("/usr/lib/libfoo.so.1: undefined symbol: PyFoo_Bar")\n'


def _fake_library(
    monkeypatch: pytest.MonkeyPatch, directory: Path, library: str, source: str | None
) -> None:
    """Make ``import library`` run ``source`` (``None``: the library is not installed)."""
    for name in [name for name in sys.modules if name.partition(".")[0] == library]:
        monkeypatch.delitem(sys.modules, name)
    if source is None:
        monkeypatch.setitem(sys.modules, library, None)  # (import raises ModuleNotFoundError)
        return
    (directory / f"{library}.py").write_text(source)
    monkeypatch.syspath_prepend(str(directory))


@pytest.mark.parametrize(("argv", "library", "extra"), COMMANDS)
def test_a_library_that_fails_to_load_is_said_installed_but_broken(
    run_cli: RunCli,
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    argv: tuple[str, ...],
    library: str,
    extra: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    _fake_library(monkeypatch, tmp_path, library, _BROKEN)
    result = run_cli(*argv)
    assert result.status == 1
    assert result.err == (
        f"rovlink {argv[0]}: {library} is installed but cannot be imported: "
        "/usr/lib/libfoo.so.1: undefined symbol: PyFoo_Bar; reinstall the "
        f"{extra} extra: pip install --upgrade --force-reinstall 'rovlink[{extra}]' "
        "(rovlink -v shows the traceback)\n"
    )


@pytest.mark.parametrize(("argv", "library", "extra"), COMMANDS)
def test_a_missing_dependency_of_the_library_is_said_with_the_install_line(
    run_cli: RunCli,
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    argv: tuple[str, ...],
    library: str,
    extra: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    _fake_library(monkeypatch, tmp_path, library, "import rovlink_absent_dependency\n")
    result = run_cli(*argv)
    assert result.status == 1
    assert result.err.endswith(f" rovlink_absent_dependency: pip install 'rovlink[{extra}]'\n"), (
        result.err
    )
    assert result.err.count("\n") == 1


@pytest.mark.parametrize(("argv", "library", "extra"), COMMANDS)
def test_a_missing_library_is_said_with_the_install_line(
    run_cli: RunCli,
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
    argv: tuple[str, ...],
    library: str,
    extra: str,
) -> None:
    monkeypatch.chdir(tmp_path)
    _fake_library(monkeypatch, tmp_path, library, None)
    result = run_cli(*argv)
    assert result.status == 1
    assert result.err.endswith(f"needs {library}: pip install 'rovlink[{extra}]'\n")
    assert result.err.count("\n") == 1


@pytest.mark.parametrize(
    ("source", "first_line"),
    [
        pytest.param(
            "import collections\ncollections.Mapping\n",
            "module 'collections' has no attribute 'Mapping'",
            id="attribute",
        ),
        pytest.param(
            "def f(async=1):\n    pass\n", "invalid syntax (aiomqtt.py, line 1)", id="syntax"
        ),
    ],
)
def test_a_library_too_old_for_this_python_is_said_installed_but_broken(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, source: str, first_line: str
) -> None:
    """Not only ImportError: a library written for an older Python can fail with any error as
    it is imported, or not compile at all."""
    monkeypatch.chdir(tmp_path)
    _fake_library(monkeypatch, tmp_path, "aiomqtt", source)
    result = run_cli("mqtt", "sim://", "--robot", "r1", "--broker", "mqtt://127.0.0.1:1")
    assert result.status == 1
    assert result.err.startswith(
        f"rovlink mqtt: aiomqtt is installed but cannot be imported: {first_line}; "
        "reinstall the mqtt extra"
    ), result.err
    assert result.err.count("\n") == 1


def test_a_submodule_missing_from_an_installed_library_is_a_broken_install(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A compiled part built for another Python is not found: ModuleNotFoundError, but for a
    module inside the installed library, which installing again would not bring."""
    monkeypatch.chdir(tmp_path)
    package = tmp_path / "matplotlib"
    package.mkdir()
    (package / "__init__.py").write_text("import matplotlib._path\n")
    for name in [name for name in sys.modules if name.partition(".")[0] == "matplotlib"]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.syspath_prepend(str(tmp_path))
    result = run_cli("plot", "dive.jsonl", "-o", "dive.png")
    assert result.status == 1
    assert result.err.startswith(
        "rovlink plot: matplotlib is installed but cannot be imported: "
        "No module named 'matplotlib._path'; reinstall the plot extra"
    ), result.err


@pytest.mark.integration
def test_verbose_shows_the_traceback_of_the_failed_import(tmp_path: Path) -> None:
    (tmp_path / "matplotlib.py").write_text(_BROKEN)
    environment = rovlink_environment()
    environment["PYTHONPATH"] = f"{tmp_path}:{environment['PYTHONPATH']}"
    argv = ("plot", "dive.jsonl", "-o", "dive.png")
    quiet, verbose = (
        subprocess.run(
            rovlink_command(*root, *argv),
            capture_output=True,
            text=True,
            env=environment,
            cwd=tmp_path,
            timeout=60,
            check=False,
        )
        for root in ((), ("-v",))
    )
    assert (quiet.returncode, verbose.returncode) == (1, 1)
    assert "Traceback" not in quiet.stderr
    assert quiet.stderr.count("\n") == 1
    assert "Traceback (most recent call last):" in verbose.stderr
    assert 'raise ImportError("/usr/lib/libfoo.so.1: undefined symbol' in verbose.stderr
    assert verbose.stderr.endswith(quiet.stderr)


def test_a_failure_of_rovlink_or_of_python_itself_is_not_blamed_on_the_extra() -> None:
    """A bug (an import of a name rovlink lacks, an error raised in the standard library) keeps
    its traceback: no library of the extra is at fault, and reinstalling it would not help."""
    with pytest.raises(ImportError, match="no_such_name"), needs_extra("web"):
        from rovlink.cli import no_such_name  # type: ignore[attr-defined]  # noqa: F401
    with pytest.raises(json.JSONDecodeError), needs_extra("web"):
        json.loads("{")


@pytest.mark.parametrize(
    "argv",
    [
        ("record", "sim://", "-o", "dive.mcap"),
        ("replay", "dive.mcap"),
        ("send", "--record", "dive.mcap", "sim://", "qd"),
    ],
    ids=["record", "replay", "send-record"],
)
def test_a_broken_recording_library_is_said_before_the_link_opens(
    run_cli: RunCli, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, argv: tuple[str, ...]
) -> None:
    """The record extra's library is imported by the recorder, not by the command: it is
    checked with the recording's name, and said in one line as the others are."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delitem(sys.modules, "rovlink.recorder.mcap_format", raising=False)
    _fake_library(monkeypatch, tmp_path, "mcap", _BROKEN)
    result = run_cli(*argv)
    assert result.status == 1
    assert result.err == (
        f"rovlink {argv[0]}: mcap is installed but cannot be imported: "
        "/usr/lib/libfoo.so.1: undefined symbol: PyFoo_Bar; reinstall the "
        "record extra: pip install --upgrade --force-reinstall 'rovlink[record]' "
        "(rovlink -v shows the traceback)\n"
    )
    assert not (tmp_path / "dive.mcap").exists()
