"""The C99 reference: generated from the command table, strict build, conformance on a PTY,
sanitizers and a fuzz run."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from rovlink.client.links import open_link
from rovlink.client.url import parse_url
from rovlink.conformance import CHECKS, SuiteOptions, run_checks, select_checks
from rovlink.protocol import c_table

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "c"
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
SANITIZE = ["-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all"]
LAYER = [str(FIRMWARE / "rovlink_proto.c"), str(FIRMWARE / "rovlink_commands.c")]
GCC = shutil.which("gcc")

needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc is not installed (.ci/debian-packages)")


def test_generated_command_table_is_up_to_date() -> None:
    header = (FIRMWARE / c_table.HEADER_NAME).read_text(encoding="ascii")
    source = (FIRMWARE / c_table.SOURCE_NAME).read_text(encoding="ascii")
    assert header == c_table.render_header(), "run: python -m rovlink.protocol.c_table firmware/c"
    assert source == c_table.render_source(), "run: python -m rovlink.protocol.c_table firmware/c"


def _build(output: Path, main: str, *flags: str) -> Path:
    assert GCC is not None
    command = [GCC, *STRICT, *flags, f"-I{FIRMWARE}", "-o", str(output), main, *LAYER, "-lm"]
    result = subprocess.run(command, capture_output=True, text=True, check=False, timeout=120)
    assert result.returncode == 0, result.stderr
    return output


@pytest.fixture(scope="module")
def host_binary(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if GCC is None:
        pytest.skip("gcc is not installed (.ci/debian-packages)")
    out = tmp_path_factory.mktemp("c") / "rovlink-host"
    return _build(out, str(FIRMWARE / "host" / "host_robot.c"), "-O2")


@pytest.fixture(scope="module")
def sanitized_binary(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if GCC is None:
        pytest.skip("gcc is not installed (.ci/debian-packages)")
    out = tmp_path_factory.mktemp("c") / "rovlink-host-asan"
    return _build(out, str(FIRMWARE / "host" / "host_robot.c"), *SANITIZE)


def _serve(binary: Path) -> Iterator[str]:
    process = subprocess.Popen(
        [str(binary)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        assert "rovlink-c ready: pty " in line, line
        yield line.split("pty ", 1)[1].split()[0]
    finally:
        process.terminate()
        _, errors = process.communicate(timeout=10)
        assert process.returncode == 0, errors  # a sanitizer report exits non-zero


@pytest.mark.integration
@pytest.mark.slow
def test_rovlink_check_passes_against_the_c_reference_with_motion(host_binary: Path) -> None:
    for pty in _serve(host_binary):
        link = open_link(parse_url(pty))
        try:
            report = run_checks(link, pty, SuiteOptions(motion=True))
        finally:
            link.close()
        assert [(r.name, r.message) for r in report.failures] == []
        assert len(report.results) == len(CHECKS)


@pytest.mark.integration
@pytest.mark.slow
def test_rovlink_check_passes_against_the_sanitized_build(sanitized_binary: Path) -> None:
    for pty in _serve(sanitized_binary):
        link = open_link(parse_url(pty))
        try:
            report = run_checks(link, pty, SuiteOptions(), select_checks())
        finally:
            link.close()
        assert [(r.name, r.message) for r in report.failures] == []


@needs_gcc
@pytest.mark.integration
def test_fuzz_run_of_the_parser_under_sanitizers(tmp_path: Path) -> None:
    binary = _build(tmp_path / "fuzz", str(FIRMWARE / "host" / "fuzz_parser.c"), *SANITIZE)
    for seed in ("1", "2"):
        result = subprocess.run(
            [str(binary), "100000", seed], capture_output=True, text=True, check=False, timeout=300
        )
        assert result.returncode == 0, result.stderr
        assert ": ok" in result.stdout
        commands = int(result.stdout.split(" commands")[0].rsplit(" ", 1)[1])
        assert commands > 1000  # the streams reach the dispatch, not only the parser
