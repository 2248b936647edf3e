"""docs/hardware.md: its C checksum passes the protocol's test vectors, and its reference of the
board's keys is the one the code generates."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from rovlink.board.pi.config import pi_config_reference
from rovlink.protocol.checksum import ALGORITHMS

DOC = Path(__file__).resolve().parents[2] / "docs" / "hardware.md"
_VECTOR = re.compile(r"^\| `([^`]+)` \| ([0-9A-F]{2}) \| `([#$][^`]+!)` \|$", re.MULTILINE)


def _vectors() -> list[tuple[str, str, str]]:
    vectors = _VECTOR.findall(DOC.read_text(encoding="utf-8"))
    assert len(vectors) == 6
    return vectors


def test_the_reference_of_the_boards_keys_is_current() -> None:
    assert pi_config_reference() in DOC.read_text(encoding="utf-8")


def test_the_vectors_in_the_doc_are_the_protocols() -> None:
    crc8 = ALGORITHMS["crc8"]
    for body, crc, frame in _vectors():
        assert f"{crc8.function(body.encode()):02X}" == crc, body
        assert frame[1:-1] == body + crc


@pytest.mark.integration
def test_the_c_checksum_in_the_doc_passes_the_test_vectors(tmp_path: Path) -> None:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        pytest.skip("no C compiler (the Debian package gcc)")
    text = DOC.read_text(encoding="utf-8")
    (code,) = re.findall(r"```c\n(.*?)```", text, re.DOTALL)
    cases = [("123456789", "F4"), *[(body, crc) for body, crc, _ in _vectors()]]
    checks = "\n".join(f'    failures += check("{body}", 0x{crc});' for body, crc in cases)
    program = tmp_path / "crc.c"
    program.write_text(
        code
        + """
#include <stdio.h>
#include <string.h>

static int check(const char *body, unsigned expected)
{
    unsigned got = rov_crc8((const uint8_t *)body, strlen(body));
    if (got != expected) {
        printf("%s: %02X, expected %02X\\n", body, got, expected);
        return 1;
    }
    return 0;
}

int main(void)
{
    int failures = 0;
"""
        + checks
        + """
    return failures;
}
""",
        encoding="utf-8",
    )
    binary = tmp_path / "crc"
    subprocess.run(
        [compiler, "-std=c99", "-Wall", "-Werror", "-o", str(binary), str(program)],
        check=True,
        timeout=60,
    )
    result = subprocess.run([str(binary)], capture_output=True, text=True, timeout=10, check=False)
    assert result.returncode == 0, result.stdout
