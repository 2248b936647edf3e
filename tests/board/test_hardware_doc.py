"""docs/hardware.md: its C checksum passes the protocol's test vectors, its reference of the
board's keys is the one the code generates, and its depth steps are the raw scale's."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from rovlink.board.pi.config import pi_config_reference
from rovlink.board.pi.pressure import RawScale
from rovlink.protocol.checksum import ALGORITHMS

DOC = Path(__file__).resolve().parents[2] / "docs" / "hardware.md"
_VECTOR = re.compile(r"^\| `([^`]+)` \| ([0-9A-F]{2}) \| `([#$][^`]+!)` \|$", re.MULTILINE)
#: "k = 1000 spans 100 m in 10 cm steps", "k 200) the raw scale spans 20 m in 2 cm steps".
_DEPTH_SCALE = re.compile(r"\bk =? ?(\d+)\D{0,20}?spans (\d+) m in (\d+) cm steps")


def _vectors() -> list[tuple[str, str, str]]:
    vectors = _VECTOR.findall(DOC.read_text(encoding="utf-8"))
    assert len(vectors) == 6
    return vectors


def test_the_reference_of_the_boards_keys_is_current() -> None:
    assert pi_config_reference() in DOC.read_text(encoding="utf-8")


def _raw_at(scale: RawScale, depth_cm: float) -> int:
    """The raw reading ``depth_cm`` of water below the surface."""
    return scale.raw(scale.surface_mbar + depth_cm * scale.density_kg_m3 * 9.80665 / 10_000)


def test_the_depth_steps_in_the_doc_are_the_raw_scales() -> None:
    """Each raw count is k / 100 cm (P13): the doc's and RawScale's sentences say what it does."""
    text = " ".join(DOC.read_text(encoding="utf-8").split())
    statements = _DEPTH_SCALE.findall(text)
    assert statements
    for k, span_m, step_cm in ((int(k), int(m), int(cm)) for k, m, cm in statements):
        scale = RawScale(zero_raw=20, k=k, surface_mbar=1013.25, density_kg_m3=997.0)
        for counts in (1, 2, 3):
            assert _raw_at(scale, counts * step_cm) == 20 + counts, (k, step_cm)
            assert _raw_at(scale, (counts + 0.4) * step_cm) == 20 + counts, (k, step_cm)
        assert _raw_at(scale, span_m * 99) < 1024 <= _raw_at(scale, span_m * 101), (k, span_m)
    assert "each count is `k / 100` cm" in text
    assert "each count is ``k / 100`` cm" in (RawScale.__doc__ or "")


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


def _unit_file() -> str:
    """The systemd unit of "Running it as a service"."""
    blocks = re.findall(r"^```ini\n(.*?)^```", DOC.read_text(encoding="utf-8"), re.DOTALL | re.M)
    assert len(blocks) == 1
    return str(blocks[0])


@pytest.mark.integration
@pytest.mark.skipif(shutil.which("systemd-analyze") is None, reason="no systemd-analyze")
def test_systemd_takes_the_unit_file(tmp_path: Path) -> None:
    # Its programs must exist for systemd to take the file: any executable stands in.
    unit = _unit_file().replace("/home/rov/rovlink/.venv/bin/rovlink", "/bin/true")
    path = tmp_path / "rovlink.service"
    path.write_text(unit, encoding="utf-8")
    result = subprocess.run(
        ["systemd-analyze", "verify", "--man=no", str(path)],
        capture_output=True,
        text=True,
        timeout=30,
        check=False,
    )
    assert result.returncode == 0, result.stderr


def test_the_unit_runs_the_controller_where_lgpio_can_make_its_pipes() -> None:
    """lgpio makes its notification pipes in the working directory as it loads; a service's is
    / unless its unit sets one, which the service's user cannot write: the leak probe found no
    pin library, and the controller did not start under systemd though it did by hand."""
    settings = dict(
        line.split("=", 1) for line in _unit_file().splitlines() if "=" in line and line[0] != "#"
    )
    # User='s home, or a runtime directory systemd makes for User=.
    writable = {"~", f"/run/{settings.get('RuntimeDirectory')}"}
    assert settings.get("WorkingDirectory") in writable, settings.get("WorkingDirectory")


def test_the_unit_outlives_its_serial_device_going_away() -> None:
    """The failsafe table promises that a serial device gone away is opened again every second:
    BindsTo= on the device would have systemd stop the controller when the adapter is unplugged
    (and not start it when it is back), the robot dead in the water for the rest of the dive.
    The unit waits for the device at boot (Requires= and After=) and lets the controller ride
    out its absence."""
    lines = _unit_file().splitlines()
    device_lines = [line for line in lines if ".device" in line and not line.startswith("#")]
    assert device_lines
    assert not [line for line in device_lines if line.startswith("BindsTo=")]
    assert "Requires=dev-serial0.device" in lines
    assert "After=dev-serial0.device" in lines
    text = " ".join(DOC.read_text(encoding="utf-8").split())
    assert "the device is opened again every second" in text
