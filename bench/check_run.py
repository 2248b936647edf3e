"""How long ``rovlink check`` takes without motion: against the simulator (in this process) and
against the C reference on a pseudo-terminal (a separate process, a real PTY), in the same run.

The suite's time is mostly the silences it must wait out (a frame that must not be answered is
watched for ``silence_s``), so both figures are close; the target is under 30 s.

    PYTHONPATH=src python bench/check_run.py
"""

from __future__ import annotations

import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from rovlink.client.links import open_link
from rovlink.client.url import parse_url
from rovlink.conformance import run_checks

TARGET_S = 30.0
FIRMWARE = Path(__file__).resolve().parents[1] / "firmware" / "c"


def timed(url: str) -> tuple[float, int, int]:
    link = open_link(parse_url(url))
    started = time.monotonic()
    try:
        report = run_checks(link, url)
    finally:
        link.close()
    return time.monotonic() - started, len(report.results), len(report.failures)


def main() -> None:
    rows = [("simulator (sim://)", *timed("sim://?seed=1"))]
    gcc = shutil.which("gcc")
    if gcc is not None:
        with tempfile.TemporaryDirectory() as directory:
            binary = Path(directory) / "rovlink-host"
            subprocess.run(
                [
                    gcc,
                    "-std=c99",
                    "-O2",
                    f"-I{FIRMWARE}",
                    "-o",
                    str(binary),
                    str(FIRMWARE / "host" / "host_robot.c"),
                    str(FIRMWARE / "rovlink_proto.c"),
                    str(FIRMWARE / "rovlink_commands.c"),
                    "-lm",
                ],
                check=True,
            )
            process = subprocess.Popen([str(binary)], stdout=subprocess.PIPE, text=True)
            try:
                assert process.stdout is not None
                pty = process.stdout.readline().split("pty ", 1)[1].split()[0]
                rows.append(("C reference on a PTY", *timed(pty)))
            finally:
                process.terminate()
                process.wait(timeout=10)
    for label, seconds, checks, failures in rows:
        verdict = "meets" if seconds < TARGET_S else "MISSES"
        print(
            f"{label:24} {seconds:5.1f} s for {checks} checks, {failures} failed "
            f"({verdict} < {TARGET_S:g} s)"
        )


if __name__ == "__main__":
    main()
