"""The README's example of the C reference's use compiles as it stands, with every warning, for
the host and for an ATmega328P, and does what it says on a few frames."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.firmware.c_build import FIRMWARE, GCC, LAYER, STRICT, build, needs_gcc

README = FIRMWARE / "README.md"
AVR_GCC = shutil.which("avr-gcc")

#: The board's side the example leaves to the reader: a UART fed from a byte string, whose
#: output is printed, and a depth sensor.
_BOARD = r"""
#include <stdio.h>
#include <string.h>
#include "rovlink_proto.h"

void controller_start(void);
void controller_poll(void);

static const char *input;
static size_t input_left;

size_t uart_read(uint8_t *buffer, size_t size) {
    size_t count = input_left < size ? input_left : size;
    memcpy(buffer, input, count);
    input += count;
    input_left -= count;
    return count;
}

void uart_write(const char *data, size_t length) { fwrite(data, 1, length, stdout); }

int32_t depth_cm(void) { return 123; }

int main(int argc, char **argv) {
    if (argc != 2) return 2;
    input = argv[1];
    input_left = strlen(input);
    controller_start();
    while (input_left) controller_poll();
    return 0;
}
"""


def _example() -> str:
    blocks: list[str] = re.findall(
        r"^```c\n(.*?)^```$", README.read_text(encoding="utf-8"), re.M | re.S
    )
    assert len(blocks) == 1, "the README has one C block, its example"
    return blocks[0]


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    if GCC is None:
        pytest.skip("gcc is not installed (.ci/debian-packages)")
    directory = tmp_path_factory.mktemp("example")
    (directory / "example.c").write_text(_example(), encoding="utf-8")
    (directory / "board.c").write_text(_BOARD, encoding="ascii")
    return directory


@needs_gcc
def test_the_readme_example_runs(example: Path) -> None:
    # Before: the README's block declared the callbacks without defining them and called
    # rl_init and rl_feed outside any function: it compiled nowhere.
    program = build(
        example / "example", [example / "example.c", example / "board.c", *LAYER], *STRICT, "-O1"
    )
    frames = "#qd!#debug1!#mgmp.200!#mgmp.256!#stop!"
    result = subprocess.run([str(program), frames], capture_output=True, check=True, timeout=10)
    output = result.stdout.decode("ascii")
    assert output.startswith("$qd.123!debug: debug output on\r\n")
    lines = output.splitlines()
    assert "debug: max PWM 200" in lines
    assert any(line.startswith("debug: dropped <mgmp.256>") for line in lines)
    assert lines[-1] == "debug: stop command: motors stopped and locked"


def test_the_readme_example_compiles_for_avr(example: Path) -> None:
    if AVR_GCC is None:
        pytest.skip("avr-gcc is not installed (.ci/debian-packages: gcc-avr, avr-libc)")
    command = [AVR_GCC, "-mmcu=atmega328p", "-Os", *STRICT, f"-I{FIRMWARE}", "-c"]
    output = example / "example.avr.o"
    result = subprocess.run(
        [*command, "-o", str(output), str(example / "example.c")],
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert result.returncode == 0, result.stderr
