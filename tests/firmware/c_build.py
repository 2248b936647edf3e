"""Building the firmware's C for the tests (the compilers, the strict flags and the protocol
layer every program links with), and running the stepped programs built from it."""

from __future__ import annotations

import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware" / "c"
GCC = shutil.which("gcc")
GXX = shutil.which("g++")
CLANG = shutil.which("clang")
#: The reference is C99 and builds without a warning, implicit conversions and shadowed names
#: included (an int of 16 bits on the small targets makes those matter).
WARNINGS = ("-Wall", "-Wextra", "-Wpedantic", "-Wconversion", "-Wsign-conversion", "-Wshadow")
STRICT = ("-std=c99", *WARNINGS, "-Werror")
#: AddressSanitizer and UBSan, the first report fatal.
SANITIZE = ("-g", "-O1", "-fsanitize=address,undefined", "-fno-sanitize-recover=all")
#: The protocol layer (generated command table included).
LAYER = (FIRMWARE / "rovlink_proto.c", FIRMWARE / "rovlink_commands.c")

needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc is not installed (.ci/debian-packages)")


def build(
    output: Path, sources: Sequence[Path | str], *flags: str, compiler: str | None = GCC
) -> Path:
    """Compile and link ``sources`` into ``output`` with ``flags``, the firmware's directory
    on the include path and the maths library; the compiler's messages if it fails."""
    assert compiler is not None
    command = [compiler, *flags, f"-I{FIRMWARE}", "-o", str(output), *map(str, sources), "-lm"]
    result = subprocess.run(command, capture_output=True, text=True, check=False, timeout=120)
    assert result.returncode == 0, result.stderr
    return output


def run_script(program: Path, script: Sequence[str], *arguments: str) -> list[list[str]]:
    """Run a stepped program (``host_robot_steps.c``, the sketch's host build) on ``script``,
    one command a line; the words of each line it shows."""
    result = subprocess.run(
        [str(program), *arguments],
        input="".join(line + "\n" for line in script),
        capture_output=True,
        text=True,
        check=True,
        timeout=30,
    )
    return [line.split() for line in result.stdout.splitlines()]


def send(data: bytes) -> str:
    """The script line that feeds ``data`` to the program's serial input."""
    return "send " + data.hex()
