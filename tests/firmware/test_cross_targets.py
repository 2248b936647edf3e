"""The C reference's protocol layer on the 32-bit and 16-bit microcontrollers teams build on,
compiled (not run) with clang, which targets them all with no other toolchain installed:

* Cortex-M0 (Raspberry Pi Pico, SAMD21 boards, STM32F0): no hardware division, strict alignment;
* Cortex-M4F (Teensy 3, STM32F4, nRF52): with a floating-point unit, so a float routine would
  not show as a call;
* RV32IMC (ESP32-C3 and other small RISC-V chips);
* MSP430: a 16-bit ``int`` and 16-bit pointers, as the ATmega328P (``test_avr.py``).

There is no C library for these targets here; ``freestanding/string.h`` declares the four
functions the layer calls, so that any other library call fails to compile (C99 has no
implicit declarations under ``-Werror``).
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.firmware.c_build import CLANG, FIRMWARE, LAYER, STRICT

LLVM_NM = shutil.which("llvm-nm")
LLVM_SIZE = shutil.which("llvm-size")
FREESTANDING = Path(__file__).with_name("freestanding")

#: The targets, by the name of a board family: clang's target triple and CPU options.
TARGETS = {
    "cortex-m0": ("--target=thumbv6m-none-eabi", "-mcpu=cortex-m0"),
    "cortex-m4f": ("--target=thumbv7em-none-eabihf", "-mcpu=cortex-m4", "-mfloat-abi=hard"),
    "rv32imc": ("--target=riscv32-unknown-elf", "-march=rv32imc"),
    "msp430": ("--target=msp430",),
}
#: What the layer may call: the string functions, its tables, and the compiler's integer
#: division and multiplication helpers where the chip has no instruction for them.
_ALLOWED_CALLS = {"memcmp", "memcpy", "memset", "strlen"}
_TABLES = re.compile(r"rl_\w+")
_INTEGER_HELPERS = re.compile(r"__aeabi_u?idiv(mod)?|__mspabi_(divu?l?|remu?l?i?|mpyi|mpyl)\w*")

pytestmark = [
    pytest.mark.integration,
    pytest.mark.skipif(
        CLANG is None or LLVM_NM is None or LLVM_SIZE is None,
        reason="clang, llvm-nm or llvm-size is not installed (.ci/debian-packages: clang, llvm)",
    ),
]


def _compile(target: str, source: Path, output: Path) -> Path:
    assert CLANG is not None
    command = [
        CLANG,
        *TARGETS[target],
        "-ffreestanding",
        *STRICT,
        "-Os",
        f"-I{FREESTANDING}",
        f"-I{FIRMWARE}",
        "-c",
        "-o",
        str(output),
        str(source),
    ]
    result = subprocess.run(command, capture_output=True, text=True, check=False, timeout=60)
    assert result.returncode == 0, result.stderr
    return output


def _sizes(object_file: Path) -> tuple[int, int, int]:
    """Text (code and constants: flash), data and bss (RAM) of an object file, bytes."""
    assert LLVM_SIZE is not None
    result = subprocess.run(
        [LLVM_SIZE, str(object_file)], capture_output=True, text=True, check=True
    )
    text, data, bss = result.stdout.splitlines()[1].split()[:3]
    return int(text), int(data), int(bss)


@pytest.mark.parametrize("target", TARGETS)
@pytest.mark.parametrize("source", LAYER, ids=lambda path: path.name)
def test_the_layer_compiles_without_a_warning_and_takes_no_ram_of_its_own(
    tmp_path: Path, target: str, source: Path
) -> None:
    text_bytes, data_bytes, bss_bytes = _sizes(_compile(target, source, tmp_path / "layer.o"))
    assert (data_bytes, bss_bytes) == (0, 0)
    assert 500 < text_bytes < 6000  # (firmware/c/README.md gives each target's figure)


@pytest.mark.parametrize("target", TARGETS)
def test_the_layer_calls_only_string_functions_and_integer_helpers(
    tmp_path: Path, target: str
) -> None:
    assert LLVM_NM is not None
    object_file = _compile(target, LAYER[0], tmp_path / "layer.o")
    result = subprocess.run(
        [LLVM_NM, "-u", str(object_file)], capture_output=True, text=True, check=True
    )
    called = {line.split()[-1] for line in result.stdout.splitlines() if line.strip()}
    assert {"memcpy", "memset"} <= called
    others = {
        name
        for name in called - _ALLOWED_CALLS
        if not _TABLES.fullmatch(name) and not _INTEGER_HELPERS.fullmatch(name)
    }
    assert others == set()


@pytest.mark.parametrize("target", TARGETS)
def test_a_link_is_the_size_the_readme_gives(tmp_path: Path, target: str) -> None:
    # The RAM the layer needs is the app's one rl_link; its size follows the target's
    # alignment (a 16-bit chip packs it as the ATmega328P does).
    expected_bytes = {"cortex-m0": 84, "cortex-m4f": 84, "rv32imc": 84, "msp430": 80}[target]
    check = tmp_path / "link_size.c"
    check.write_text(
        '#include "rovlink_proto.h"\n'
        f"typedef char link_size[sizeof(rl_link) == {expected_bytes} ? 1 : -1];\n",
        encoding="ascii",
    )
    _compile(target, check, tmp_path / "link_size.o")
