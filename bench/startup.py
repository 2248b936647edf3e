"""Start-up time of the ``rovlink`` command against ``python -c pass`` on the same interpreter.

    python bench/startup.py [--runs 30]

Each command runs as a subprocess, as a person would run it; the figure is the best wall time of
``--runs`` runs (the least disturbed by other load), and the ratio is to ``python -c pass``
measured in the same run. ``rovlink`` is run through its console script when it is installed
beside the interpreter, else as ``python -m rovlink``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CAPTURE_BYTES = 1024
#: The commands run as on a user's machine: Python writes and reuses its compiled ``.pyc`` files
#: (an environment that forbids them would time the compiler at every start).
USER_ENVIRONMENT = {
    name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"
}


def capture() -> bytes:
    """A 1 KB capture: polls, replies, a command, a debug line."""
    block = b"#qsa!$qd.57!$qr.134!$q.l.0!$qro.+1!$qpi.-2!$qhe.275!#th.90.30!\r\npid out=+12\r\n"
    return (block * (CAPTURE_BYTES // len(block) + 1))[:CAPTURE_BYTES]


def rovlink_command() -> list[str]:
    """The console script next to this interpreter, else ``python -m rovlink``."""
    script = Path(sys.executable).with_name("rovlink")
    if script.exists():
        return [str(script)]
    found = shutil.which("rovlink")
    return [found] if found else [sys.executable, "-m", "rovlink"]


def best_wall_time_s(command: list[str], runs: int) -> float:
    """The shortest wall time of ``runs`` runs of ``command`` (output discarded)."""
    best_s = float("inf")
    for _ in range(runs):
        started = time.perf_counter()
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=USER_ENVIRONMENT)
        best_s = min(best_s, time.perf_counter() - started)
    return best_s


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=30, help="runs per command (default: 30)")
    args = parser.parse_args()
    rovlink = rovlink_command()
    with tempfile.TemporaryDirectory() as directory:
        capture_path = Path(directory) / "capture.bin"
        capture_path.write_bytes(capture())
        commands = {
            "python -c pass": [sys.executable, "-c", "pass"],
            "rovlink --version": [*rovlink, "--version"],
            f"rovlink decode (a {CAPTURE_BYTES} B capture)": [
                *rovlink,
                "decode",
                str(capture_path),
            ],
            "rovlink --help": [*rovlink, "--help"],
        }
        for command in commands.values():  # warm the file cache and .pyc files
            subprocess.run(command, check=True, stdout=subprocess.DEVNULL, env=USER_ENVIRONMENT)
        # Interleaved rounds, so that a burst of load touches every command alike.
        best_s = dict.fromkeys(commands, float("inf"))
        rounds = 5
        for _ in range(rounds):
            for name, command in commands.items():
                best_s[name] = min(
                    best_s[name], best_wall_time_s(command, max(args.runs // rounds, 1))
                )
    print(f"Python {sys.version.split()[0]}, {' '.join(rovlink)}; best of {args.runs} runs")
    baseline_s = best_s["python -c pass"]
    print(f"{'command':<40} {'ms':>7} {'× python -c pass':>17}")
    for name, seconds in best_s.items():
        print(f"{name:<40} {seconds * 1000:7.1f} {seconds / baseline_s:17.2f}")


if __name__ == "__main__":
    main()
