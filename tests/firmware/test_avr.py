"""The C reference on an 8-bit target: compiled (not run) for an ATmega328P, the Arduino Uno's
chip (2 KB of RAM, a 16-bit ``int``), with avr-gcc."""

from __future__ import annotations

import functools
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.firmware.c_build import FIRMWARE, LAYER, STRICT, WARNINGS

AVR_GCC = shutil.which("avr-gcc")
AVR_GXX = shutil.which("avr-g++")
AVR_OBJDUMP = shutil.which("avr-objdump")
AVR_NM = shutil.which("avr-nm")
#: The Uno's chip, built for size as the Arduino IDE builds.
TARGET = ("-mmcu=atmega328p", "-Os")
SKETCH = FIRMWARE / "arduino" / "rovlink_controller" / "rovlink_controller.ino"
HOST = Path(__file__).with_name("arduino_host")

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(
        AVR_GCC is None or AVR_GXX is None or AVR_OBJDUMP is None or AVR_NM is None,
        reason="avr-gcc is not installed (.ci/debian-packages: gcc-avr, avr-libc)",
    ),
]


def _compile(compiler: str | None, source: Path, output: Path, *flags: str) -> Path:
    assert compiler is not None
    command = [compiler, *TARGET, *flags, f"-I{FIRMWARE}", "-c", "-o", str(output), str(source)]
    result = subprocess.run(command, capture_output=True, text=True, check=False, timeout=60)
    assert result.returncode == 0, result.stderr
    return output


def _sections(object_file: Path) -> dict[str, int]:
    """The size of each section of an object file, by name."""
    assert AVR_OBJDUMP is not None
    result = subprocess.run(
        [AVR_OBJDUMP, "-h", str(object_file)], capture_output=True, text=True, check=True
    )
    sections = {}
    for line in result.stdout.splitlines():
        words = line.split()
        if len(words) >= 3 and words[0].isdigit():
            sections[words[1]] = int(words[2], 16)
    return sections


def _in_ram(sections: dict[str, int]) -> dict[str, int]:
    """The sections an AVR program keeps in RAM: its variables and, unlike most targets, its
    constants (.rodata is copied to RAM at start); only PROGMEM data stays in flash."""
    return {
        name: size
        for name, size in sections.items()
        if size and name.startswith((".data", ".bss", ".rodata"))
    }


@pytest.mark.parametrize("source", LAYER, ids=lambda path: path.name)
def test_the_layer_takes_no_ram_of_its_own_on_avr(tmp_path: Path, source: Path) -> None:
    # Before: the layer's 789 bytes of debug and drop texts, and its hex digits and table of
    # checksum lines, were constants in RAM: 820 of the Uno's 2048 bytes. Its texts are in
    # flash now (RL_TEXT), like the command table. (Without a warning with a 16-bit int, too.)
    sections = _sections(_compile(AVR_GCC, source, tmp_path / "layer.o", *STRICT))
    assert _in_ram(sections) == {}


#: What the layer may call: a few string functions, flash reads, its tables, and libgcc's integer
#: multiplication and division (32-bit numbers on an 8-bit chip).
_ALLOWED_CALLS = {"memcmp", "memcpy", "memcpy_P", "memset", "strlen"}
_TABLES = re.compile(r"rl_\w+")
_INTEGER_HELPERS = re.compile(r"__(u?divmod|u?mul)\w*[hsd]i\d")


def test_the_layer_calls_no_malloc_stdio_or_float_on_avr(tmp_path: Path) -> None:
    # As the README promises: no malloc, no stdio, no float (a float routine or printf would
    # cost kilobytes of flash on an 8-bit chip).
    assert AVR_NM is not None
    object_file = _compile(AVR_GCC, LAYER[0], tmp_path / "layer.o", *STRICT)
    result = subprocess.run(
        [AVR_NM, "-u", str(object_file)], capture_output=True, text=True, check=True
    )
    called = {line.split()[-1] for line in result.stdout.splitlines() if line.strip()}
    assert "memcpy_P" in called  # (the tables are read from flash)
    others = {
        name
        for name in called - _ALLOWED_CALLS
        if not _TABLES.fullmatch(name) and not _INTEGER_HELPERS.fullmatch(name)
    }
    assert others == set()


#: The stack the layer may take at its deepest on AVR (firmware/c/README.md says "about 270").
_STACK_BYTES = 280


def _deepest_stack_bytes(object_file: Path, frames: Path, function: str) -> int:
    """The most stack ``function`` can take: its frame and, for each call it makes within the
    layer, the 2-byte return address and the callee's deepest; the app's callbacks (indirect
    calls) and the C library's routines not counted. The frames are gcc's -fstack-usage."""
    assert AVR_OBJDUMP is not None
    frame_bytes = {}
    for line in frames.read_text(encoding="ascii").splitlines():
        where, size, _ = line.split("\t")
        frame_bytes[where.rsplit(":", 1)[1]] = int(size)
    listing = subprocess.run(
        [AVR_OBJDUMP, "-dr", str(object_file)], capture_output=True, text=True, check=True
    ).stdout
    at_address: dict[int, str] = {}
    calls: dict[str, set[str]] = {}
    current = ""
    for line in listing.splitlines():
        if start := re.match(r"([0-9a-f]+) <([^>]+)>:", line):
            current = start[2]
            at_address[int(start[1], 16)] = current
            calls[current] = set()
        elif call := re.search(r"R_AVR_CALL\s+\.text(?:\+0x([0-9a-f]+))?$", line):
            calls[current].add(call[1] or "0")

    @functools.cache
    def deepest(name: str) -> int:
        callees = (at_address[int(offset, 16)] for offset in calls[name])
        return frame_bytes[name] + max((2 + deepest(callee) for callee in callees), default=0)

    return deepest(function)


def test_the_layers_deepest_stack_on_avr(tmp_path: Path) -> None:
    # Before: 309 bytes (a debug line built in one buffer and copied into another); now
    # one buffer. The app's callbacks come on top, as the README says.
    object_file = _compile(AVR_GCC, LAYER[0], tmp_path / "layer.o", *STRICT, "-fstack-usage")
    frames = tmp_path / "layer.su"
    assert 200 < _deepest_stack_bytes(object_file, frames, "rl_feed") <= _STACK_BYTES


def test_a_link_takes_79_bytes_of_ram_on_avr(tmp_path: Path) -> None:
    # As the README says: the RAM the layer needs is the app's one rl_link.
    check = tmp_path / "link_size.c"
    check.write_text(
        '#include "rovlink_proto.h"\n'
        "typedef char link_is_79_bytes[sizeof(rl_link) == 79 ? 1 : -1];\n",
        encoding="ascii",
    )
    _compile(AVR_GCC, check, tmp_path / "link_size.o", "-std=c99")


def test_the_sketch_compiles_for_avr_without_a_warning_and_keeps_its_texts_in_flash(
    tmp_path: Path,
) -> None:
    # Over the host stand-in for the Arduino core (tests/firmware/arduino_host): the sketch's
    # own code with a 16-bit int. Before: ten int32_t values narrowed to int without a cast,
    # and 285 bytes of debug texts in RAM (now rl_debug_flash and RL_TEXT).
    flags = ("-std=c++11", *WARNINGS, "-Werror", f"-I{HOST}", "-x", "c++")
    sections = _sections(_compile(AVR_GXX, SKETCH, tmp_path / "sketch.o", *flags))
    assert [name for name in _in_ram(sections) if name.startswith(".rodata.str")] == []
    assert sections.get(".progmem.data", 0) > 200  # (its texts, where they went)
