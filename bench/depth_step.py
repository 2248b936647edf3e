"""Depth-mode step response of the default vehicle with the default gains.

The simulated robot floats at the surface; a host unlocks it, waits, commands ``#mvd.100!`` and
keeps the link alive with ``#qd!`` twice a second, as a real host would. The script prints the
overshoot, the time after which the depth stays within ±5 cm, and the RMS error over the minute
that follows, for several seeds, against the targets; and plots the first seed's run.

    PYTHONPATH=src python bench/depth_step.py [--seeds 10] [--plot docs/depth_step.png]
"""

from __future__ import annotations

import argparse
import math
import statistics
from dataclasses import dataclass
from pathlib import Path

from rovlink.sim import SimulatedRobot

TARGET_CM = 100
BAND_CM = 5.0
SETTLE_BEFORE_S = 5.0  # at the surface before the step
AFTER_STEP_S = 120.0
KEEP_ALIVE_S = 0.5
RMS_WINDOW_S = 60.0

TARGET_OVERSHOOT_CM = 10.0
TARGET_SETTLE_S = 20.0
TARGET_RMS_CM = 3.0


@dataclass
class StepRun:
    """One step: time after the step (s), true depth (cm), measured depth qd (cm)."""

    seed: int
    times_s: list[float]
    depths_cm: list[float]
    measured_cm: list[int]

    @property
    def overshoot_cm(self) -> float:
        return max(0.0, max(self.depths_cm) - TARGET_CM)

    @property
    def settle_s(self) -> float:
        """The time after which the true depth never leaves ±5 cm of the target again."""
        last_outside = 0.0
        for time_s, depth_cm in zip(self.times_s, self.depths_cm, strict=True):
            if abs(depth_cm - TARGET_CM) > BAND_CM:
                last_outside = time_s
        return last_outside

    def rms_cm(self, start_s: float, seconds: float = RMS_WINDOW_S) -> float:
        errors = [
            (depth_cm - TARGET_CM) ** 2
            for time_s, depth_cm in zip(self.times_s, self.depths_cm, strict=True)
            if start_s <= time_s < start_s + seconds
        ]
        return math.sqrt(sum(errors) / len(errors))


def run_step(seed: int) -> StepRun:
    """The step on a fresh robot, sampled every tick."""
    robot = SimulatedRobot(seed=seed)
    controller = robot.controller
    ticks_per_query = round(KEEP_ALIVE_S / robot.tick_s)
    controller.receive(b"#start!")
    for _ in range(round(SETTLE_BEFORE_S / KEEP_ALIVE_S)):
        robot.advance(KEEP_ALIVE_S)
        controller.receive(b"#qd!")
    controller.receive(b"#mvd.%d!" % TARGET_CM)
    controller.read_output()
    start_s = robot.time_s
    run = StepRun(seed, [], [], [])
    for tick in range(round(AFTER_STEP_S / robot.tick_s)):
        if tick % ticks_per_query == 0:
            controller.receive(b"#qd!")
        robot.step()
        run.times_s.append(robot.time_s - start_s)
        run.depths_cm.append(robot.vehicle.depth_m * 100.0)
        run.measured_cm.append(controller.depth_cm)
    assert not controller.locked, "the watchdog tripped: the keep-alive is broken"
    return run


def plot(run: StepRun, path: Path) -> None:
    """Depth against target over the first 80 s after the step."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [i for i, time_s in enumerate(run.times_s) if time_s <= 80.0]
    times = [run.times_s[i] for i in shown]
    figure, axes = plt.subplots(figsize=(8, 4.2), dpi=110)
    axes.axhspan(
        TARGET_CM - BAND_CM, TARGET_CM + BAND_CM, color="tab:green", alpha=0.12, label="±5 cm"
    )
    axes.plot(times, [TARGET_CM] * len(times), color="tab:green", linestyle="--", label="target")
    axes.plot(
        times,
        [run.measured_cm[i] for i in shown],
        color="tab:orange",
        linewidth=0.6,
        alpha=0.7,
        label="measured depth (qd)",
    )
    axes.plot(
        times,
        [run.depths_cm[i] for i in shown],
        color="tab:blue",
        linewidth=1.4,
        label="true depth",
    )
    axes.axvline(run.settle_s, color="grey", linewidth=0.8, linestyle=":")
    axes.set_xlabel("time after #mvd.100! (s)")
    axes.set_ylabel("depth (cm)")
    axes.set_ylim(-5, 120)
    axes.set_title(
        f"Depth step 0 → 100 cm, default gains and vehicle (seed {run.seed}): "
        f"overshoot {run.overshoot_cm:.1f} cm, settled {run.settle_s:.1f} s",
        fontsize=9,
    )
    axes.legend(loc="lower right", fontsize=8)
    axes.grid(alpha=0.3)
    figure.tight_layout()
    figure.savefig(path)
    plt.close(figure)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--seeds", type=int, default=10, help="how many seeds to run")
    parser.add_argument("--plot", type=Path, help="write the first seed's plot here (PNG)")
    arguments = parser.parse_args()

    runs = [run_step(seed) for seed in range(1, arguments.seeds + 1)]
    print(
        f"{'seed':>4} {'overshoot cm':>12} {'settled s':>9} {'RMS cm (settled+60 s)':>22} "
        f"{'RMS cm (20–80 s)':>17}"
    )
    for run in runs:
        print(
            f"{run.seed:>4} {run.overshoot_cm:>12.2f} {run.settle_s:>9.2f} "
            f"{run.rms_cm(run.settle_s):>22.2f} {run.rms_cm(20.0):>17.2f}"
        )
    worst_overshoot = max(run.overshoot_cm for run in runs)
    worst_settle = max(run.settle_s for run in runs)
    worst_rms = max(max(run.rms_cm(run.settle_s), run.rms_cm(20.0)) for run in runs)
    print(
        f"worst of {len(runs)}: overshoot {worst_overshoot:.2f} cm (target ≤ "
        f"{TARGET_OVERSHOOT_CM:g}), settled {worst_settle:.2f} s (target ≤ {TARGET_SETTLE_S:g}), "
        f"RMS {worst_rms:.2f} cm (target ≤ {TARGET_RMS_CM:g})"
    )
    print(f"median settle {statistics.median(run.settle_s for run in runs):.2f} s")
    met = (
        worst_overshoot <= TARGET_OVERSHOOT_CM
        and worst_settle <= TARGET_SETTLE_S
        and worst_rms <= TARGET_RMS_CM
    )
    print("targets met" if met else "TARGETS MISSED")
    if arguments.plot:
        plot(runs[0], arguments.plot)
        print(f"plot: {arguments.plot}")


if __name__ == "__main__":
    main()
