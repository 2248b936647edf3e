"""The C99 reference: generated from the command table, strict build, conformance on a PTY,
sanitizers and a fuzz run."""

from __future__ import annotations

import os
import shutil
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

import pytest

from rovlink.client.links import Link, open_link
from rovlink.client.url import parse_url
from rovlink.conformance import CHECKS, SuiteOptions, run_checks, select_checks
from rovlink.controller import Attitude, ControllerConfig, Hardware
from rovlink.controller.controller import Controller
from rovlink.protocol import COMMANDS, RESPONSES, Argument, Decoder, Frame, Kind, Spec, c_table
from tests.firmware.c_build import (
    CLANG,
    FIRMWARE,
    GCC,
    LAYER,
    SANITIZE,
    STRICT,
    build,
)


def test_generated_command_table_is_up_to_date() -> None:
    header = (FIRMWARE / c_table.HEADER_NAME).read_text(encoding="ascii")
    source = (FIRMWARE / c_table.SOURCE_NAME).read_text(encoding="ascii")
    assert header == c_table.render_header(), "run: python -m rovlink.protocol.c_table firmware/c"
    assert source == c_table.render_source(), "run: python -m rovlink.protocol.c_table firmware/c"


def test_the_c_table_refuses_a_range_its_16_bit_fields_cannot_hold(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Before: a range past 32767 was written into the int16_t fields as it was, and a compiler
    # without -Werror truncated it without a word (40000 became -25536).
    wide = Spec("wide", Kind.COMMAND, "a wide range", (Argument("count", 0, 40000),))
    monkeypatch.setattr(c_table, "COMMANDS", (*COMMANDS, wide))
    with pytest.raises(ValueError, match=r"wide: the range 0\.\.40000 of count does not fit"):
        c_table.render_source()


def test_the_c_table_names_have_room_for_the_longest_reply_name(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Before: the name field was sized by the commands' spellings alone; a reply named longer
    # filled it without its NUL (C allows that without a word) and strlen read past it.
    long_reply = Spec("qtemperature", Kind.RESPONSE, "a long reply", (Argument("deg", 0, 99),))
    monkeypatch.setattr(c_table, "RESPONSES", (*RESPONSES, long_reply))
    assert "#define RL_NAME_BYTES 13\n" in c_table.render_header()


#: Every C source of the reference: the layer, the host robot, its stepped build, the fuzz run
#: and the replay of the differential tests.
_SOURCES = (
    *LAYER,
    FIRMWARE / "host" / "host_robot.c",
    FIRMWARE / "host" / "fuzz_parser.c",
    FIRMWARE / "host" / "replay.c",
    Path(__file__).with_name("host_robot_steps.c"),
)
_COMPILERS = {"gcc": GCC, "clang": CLANG}


@pytest.mark.integration
@pytest.mark.parametrize("compiler", sorted(_COMPILERS))
@pytest.mark.parametrize("flags", [("-O2",), SANITIZE], ids=["optimised", "sanitizers"])
def test_every_c_source_compiles_without_a_warning(
    tmp_path: Path, compiler: str, flags: Sequence[str]
) -> None:
    # Before: -Wconversion and -Wsign-conversion warned in the CRC-8 (clang, and gcc in the
    # sanitizers' build). Compiled only, each source to its object file.
    executable = _COMPILERS[compiler]
    if executable is None:
        pytest.skip(f"{compiler} is not installed (.ci/debian-packages)")
    command = [executable, *STRICT, *flags, f"-I{FIRMWARE}", "-c", *map(str, _SOURCES)]
    result = subprocess.run(
        command, cwd=tmp_path, capture_output=True, text=True, check=False, timeout=120
    )
    assert result.returncode == 0, result.stderr


def _build(output: Path, main: str, *flags: str) -> Path:
    return build(output, [main, *LAYER], *STRICT, *flags)


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


@pytest.mark.integration
@pytest.mark.parametrize(("compiler", "seed"), [("gcc", "1"), ("clang", "2")])
def test_fuzz_run_of_the_parser_under_sanitizers(tmp_path: Path, compiler: str, seed: str) -> None:
    executable = _COMPILERS[compiler]
    if executable is None:
        pytest.skip(f"{compiler} is not installed (.ci/debian-packages)")
    source = FIRMWARE / "host" / "fuzz_parser.c"
    binary = build(tmp_path / "fuzz", [source, *LAYER], *STRICT, *SANITIZE, compiler=executable)
    result = subprocess.run(
        [str(binary), "100000", seed], capture_output=True, text=True, check=False, timeout=300
    )
    assert result.returncode == 0, result.stderr
    assert ": ok" in result.stdout
    commands = int(result.stdout.split(" commands")[0].rsplit(" ", 1)[1])
    assert commands > 1000  # the streams reach the dispatch, not only the parser


#: Every kind of setting change in debug mode, and the repeats that change nothing (P5, P11).
_SETTINGS_STREAM = (
    b"#debug1!#debug1!#mvdirect.1!#start!#th.90.40!#mvdirect.0!#mvd.100!#mvdirect.0!"
    b"#mvdirect.1!#mvs.+10!#th.360.100!#start!#mgmp.255!#mvpdp.99!#mvpdd.6!#mvpdi.0!"
    b"#sdz.20!#sdk.200!#slreset!#h+!#h-!#stop!#stop!#crcon!#crcoff!#debug0!"
)


class _AtTheSurface:
    """Hardware as the C host's robot is at start: at the surface (raw 20), still."""

    def now_s(self) -> float:
        return 0.0

    def set_duties(self, duties: Sequence[int]) -> None:
        pass

    def read_raw(self) -> int:
        return 20

    def read_attitude(self) -> Attitude:
        return Attitude(0.0, 0.0, 0.0)

    def fired_since_last_read(self) -> bool:
        return False

    def drive(self, direction: int) -> None:
        pass


def _python_debug_lines(stream: bytes) -> list[str]:
    still = _AtTheSurface()
    hardware = Hardware(
        thrusters=still, pressure=still, imu=still, leak=still, claw=still, clock=still
    )
    controller = Controller(ControllerConfig(), hardware)
    controller.receive(stream)
    return controller.read_output().decode("ascii").splitlines()


def _read_until(link: Link, done: Callable[[bytes], bool], timeout_s: float = 5.0) -> bytes:
    received = b""
    deadline = time.monotonic() + timeout_s
    while not done(received):
        assert time.monotonic() < deadline, f"timed out; so far {received!r}"
        received += link.read_available(0.05)
    return received


@pytest.mark.integration
def test_the_c_reference_writes_the_python_controllers_debug_line_for_every_setting(
    host_binary: Path,
) -> None:
    # Before: no line for mvd, mvs, th, mgmp, the gains, sdz, sdk, slreset, h+ and h- (P5).
    expected = _python_debug_lines(_SETTINGS_STREAM)
    assert "debug: max PWM 255 (was 255)" in expected
    for pty in _serve(host_binary):
        link = open_link(parse_url(pty))
        try:
            link.write(_SETTINGS_STREAM)
            received = _read_until(link, lambda got: b"debug output off\r\n" in got)
        finally:
            link.close()
        assert received.decode("ascii").splitlines() == expected


def _depth_cm(link: Link) -> int:
    link.write(b"#qd!")
    received = _read_until(link, lambda got: b"!" in got)
    (frame,) = [event for event in Decoder().feed(received) if isinstance(event, Frame)]
    return int(frame.message.values[0])


def _wait_for_depth(link: Link, deeper_than_cm: int, timeout_s: float = 5.0) -> int:
    deadline = time.monotonic() + timeout_s
    while (depth := _depth_cm(link)) <= deeper_than_cm:
        assert time.monotonic() < deadline, f"still at {depth} cm, not below {deeper_than_cm}"
    return depth


@pytest.mark.integration
def test_a_repeated_start_keeps_the_set_points_of_the_c_reference(host_binary: Path) -> None:
    # Before: every #start! (and every #mvdirect!) cleared the set-points: a dive stopped.
    for pty in _serve(host_binary):
        link = open_link(parse_url(pty))
        try:
            link.write(b"#start!#mvdirect.1!#mvs.-50!")
            depth = _wait_for_depth(link, 20)
            link.write(b"#start!#mvdirect.1!")  # (both change nothing: P11, a no-op start)
            _wait_for_depth(link, depth + 80)  # (a stopped dive coasts some 20 cm, not 80)
        finally:
            link.write(b"#stop!")
            link.close()


def _write_until_full(pty: str, data: bytes, times: int) -> int:
    """Write ``data`` to ``pty`` up to ``times`` times without waiting; how many went in."""
    writer = os.open(pty, os.O_WRONLY | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        for written in range(times):
            try:
                os.write(writer, data)
            except BlockingIOError:  # (the robot's input is full: it has stopped reading)
                return written
        return times
    finally:
        os.close(writer)


@pytest.mark.integration
def test_the_host_build_runs_on_while_nobody_reads_its_output(host_binary: Path) -> None:
    # A UART sends whether or not anyone listens; a pseudo-terminal nobody reads fills up.
    # Before: the host build waited in write() for a reader for ever: no tick, no link-loss
    # failsafe, no more input read, and SIGTERM or Ctrl-C did not stop it (write() was
    # retried on EINTR).
    process = subprocess.Popen(
        [str(host_binary)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert process.stdout is not None
        pty = process.stdout.readline().split("pty ", 1)[1].split()[0]
        _write_until_full(pty, b"#qhe!" * 20, 5000)  # up to 500 KB of replies nobody reads
        deadline = time.monotonic() + 2.0
        while _write_until_full(pty, b"#qhe!", 1) == 0:  # the robot reads its input again
            assert time.monotonic() < deadline, "the host build stopped reading its input"
            time.sleep(0.01)
    finally:
        process.terminate()
        try:
            process.communicate(timeout=2)
        except subprocess.TimeoutExpired:
            process.kill()
            process.communicate()
            pytest.fail("the host build did not stop on SIGTERM")


@pytest.mark.integration
@pytest.mark.parametrize(
    ("arguments", "error"),
    [
        (["--leak", "30"], "unknown option --leak"),
        (["--leak-at"], "--leak-at takes seconds, 0 or more, not ''"),
        (["--leak-at", "30s"], "--leak-at takes seconds, 0 or more, not '30s'"),
        (["--leak-at", "-1"], "--leak-at takes seconds, 0 or more, not '-1'"),
    ],
)
def test_the_host_build_refuses_a_mistyped_option(
    host_binary: Path, arguments: list[str], error: str
) -> None:
    # Before: an unknown option or a bad value was ignored (--leak-at 30s leaked at 30 s,
    # --leak-at 1O at 1 s, --leak 30 never): the host build served a robot other than the one
    # asked for, without a word.
    try:
        result = subprocess.run(
            [str(host_binary), *arguments], capture_output=True, text=True, check=False, timeout=10
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"{arguments}: the host build started instead of refusing them")
    assert result.returncode == 2
    assert error in result.stderr
    assert result.stdout == ""


@pytest.mark.integration
def test_the_makefile_builds_and_fuzzes_as_the_readme_says(tmp_path: Path) -> None:
    # The README's `make` and `make fuzz`, run as a firmware engineer runs them: with no CC
    # given. Before: `CC ?= gcc` kept make's own default, cc (clang on some systems), and
    # `make commands` called `python`, which Debian does not have.
    if GCC is None:
        pytest.skip("gcc is not installed (.ci/debian-packages)")
    make = shutil.which("make")
    if make is None:
        pytest.skip("make is not installed")
    copy = tmp_path / "c"
    shutil.copytree(FIRMWARE, copy, ignore=shutil.ignore_patterns("build"))
    environment = {name: value for name, value in os.environ.items() if name != "CC"}
    result = subprocess.run(
        [make, "all", "fuzz"],
        cwd=copy,
        env=environment,
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    compiles = [line for line in result.stdout.splitlines() if " -std=c99 " in line]
    assert compiles
    assert all(line.startswith("gcc ") for line in compiles), compiles
    assert "fuzz-parser: 200000 iterations" in result.stdout
    assert (copy / "build" / "rovlink-host").is_file()
    planned = subprocess.run(
        [make, "-n", "commands"],
        cwd=copy,
        env=environment,
        capture_output=True,
        text=True,
        check=True,
        timeout=60,
    )
    assert planned.stdout.startswith("python3 -m rovlink.protocol.c_table ."), planned.stdout
