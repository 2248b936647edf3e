"""The README's example of the C reference's use compiles as it stands, with every warning, for
the host and for an ATmega328P, and does what it says on a few frames."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.firmware.c_build import FIRMWARE, GCC, LAYER, STRICT, build, needs_gcc

pytestmark = pytest.mark.integration

README = FIRMWARE / "README.md"
AVR_GCC = shutil.which("avr-gcc")

#: The board's side the example leaves to the reader: a UART fed from a byte string, whose
#: output is printed, and a depth sensor.
_BOARD = r"""
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "rovlink_proto.h"

void controller_start(void);
void controller_poll(void);
void controller_tick(uint32_t now_ms);

static const char *input;
static size_t input_left;

size_t uart_read(uint8_t *buffer, size_t size) {
    size_t count = input_left < size ? input_left : size;
    memcpy(buffer, input, count);
    input += count;
    input_left -= count;
    return count;
}

static unsigned long writes;

void uart_write(const char *data, size_t length) {
    writes++;
    fwrite(data, 1, length, stdout);
}

int32_t depth_cm(void) { return 123; }

void outputs_off(void) { fputs("<outputs off>", stdout); }

/* The frames of argv[1], then with argv[2] (a clock's first reading, ms) 3 s of 10 ms ticks
 * without a frame: "@MS" after each tick that wrote, MS since the first tick. */
int main(int argc, char **argv) {
    unsigned long tick;
    uint32_t start_ms;
    if (argc != 2 && argc != 3) return 2;
    input = argv[1];
    input_left = strlen(input);
    controller_start();
    while (input_left) controller_poll();
    if (argc == 2) return 0;
    start_ms = (uint32_t)strtoul(argv[2], NULL, 10);
    for (tick = 0; tick <= 300; tick++) {
        unsigned long before = writes;
        controller_tick(start_ms + (uint32_t)(tick * 10));
        if (writes != before) printf("@%lu\n", tick * 10);
    }
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
    assert lines[-1] == "<outputs off>debug: stop command: motors stopped and locked"


@needs_gcc
@pytest.mark.parametrize("start_ms", [0, 2**32 - 1000], ids=["clock-at-0", "clock-wraps"])
def test_the_readme_example_stops_and_locks_when_the_link_is_lost(
    example: Path, start_ms: int
) -> None:
    # Before: the example, "the whole of what a controller's code does with the layer", had no
    # link-loss failsafe (P17): a port begun from it kept its thrusters running on a dead link.
    program = build(
        example / "example", [example / "example.c", example / "board.c", *LAYER], *STRICT, "-O1"
    )
    frames = "#debug1!#start!"
    result = subprocess.run(
        [str(program), frames, str(start_ms)], capture_output=True, check=True, timeout=10
    )
    after_frames = result.stdout.decode("ascii").split("motors unlocked\r\n", 1)[1]
    # (the first tick that sees the frames counts from itself: 2 s later is the tick at 2010 ms;
    # a clock compared as now > last + 2000 stopped the robot at the wrap, 1 s in)
    assert after_frames == (
        "<outputs off>debug: failsafe: no valid frame for 2 s: motors stopped and locked\r\n@2010\n"
    )


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
