"""Depth-PID autotune on the three simulated vehicles and five noise seeds each, with heave waves,
against the default gains measured in the same run.

Each run: the relay experiment in direct mode around 100 cm, the default rule (heave-poles),
then a 0 → 100 cm step with the tuned gains; the same step with the default gains (40, 30, 20)
is the peer. Figures from the true (simulated) depth, as in bench/depth_step.py. The simulated
robot is stepped by hand under a real client, so minutes of experiment take seconds.

    PYTHONPATH=src python bench/tune.py [--seeds 5]
"""

from __future__ import annotations

import argparse

from rovlink.client import Client, ClientOptions
from rovlink.client.links import PortLink
from rovlink.controller.config import DepthPidConfig
from rovlink.sim.port import open_port
from rovlink.sim.presets import PRESETS
from rovlink.tuning import (
    RULES,
    DepthLimits,
    GainScales,
    Plant,
    ProtocolGains,
    RelaySettings,
    StepSettings,
    autotune,
    run_step,
)
from rovlink.tuning.verify import StepMetrics

TARGETS = {"overshoot_cm": 5.0, "settling_s": 10.0, "rms_cm": 2.0}
STEP = StepSettings(from_cm=0, to_cm=100)


def _plant(preset: str, seed: int) -> tuple[Plant, Client]:
    port = open_port(seed=seed, preset=preset, manual=True, timeout=0.05)
    options = ClientOptions(keepalive_s=None, motion_timeout_s=None, boot_timeout_s=None)
    client = Client(PortLink(port, "sim"), options)
    plant = Plant(
        client,
        DepthLimits(0, 400),
        clock=lambda: port.robot.time_s,
        sleep=port.advance,
        truth=lambda: port.vehicle.depth_m * 100.0,
    )
    return plant, client


def tuned(preset: str, seed: int, scales: GainScales) -> tuple[ProtocolGains, StepMetrics]:
    plant, client = _plant(preset, seed)
    try:
        result = autotune(plant, RelaySettings(), RULES["heave-poles"], scales, STEP)
    finally:
        client.close()
    assert result.step is not None
    assert result.step.true is not None
    return result.gains, result.step.true


def default(preset: str, seed: int, gains: ProtocolGains) -> StepMetrics:
    plant, client = _plant(preset, seed)
    try:
        client.start()
        step = run_step(plant, gains, STEP)
        plant.stop()
    finally:
        client.close()
    assert step.true is not None
    return step.true


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    config = DepthPidConfig()
    scales = GainScales(config.kp_scale, config.ki_scale, config.kd_scale)
    reset_gains = ProtocolGains(config.kp, config.ki, config.kd)
    worst: dict[str, dict[str, float]] = {"tuned": {}, "default": {}}
    print(
        "| vehicle | seed | tuned gains | overshoot cm | settle s | RMS cm |"
        " default gains: overshoot cm | settle s | RMS cm |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for preset, vehicle in PRESETS.items():
        for seed in range(1, args.seeds + 1):
            gains, mine = tuned(preset, seed, scales)
            peer = default(preset, seed, reset_gains)
            for label, metrics in (("tuned", mine), ("default", peer)):
                for name in TARGETS:
                    worst[label][name] = max(worst[label].get(name, 0.0), getattr(metrics, name))
            print(
                f"| {preset} ({vehicle.mass_kg:g} kg) | {seed} | {gains.kp} {gains.ki} {gains.kd}"
                f" | {mine.overshoot_cm:.1f} | {mine.settling_s:.1f} | {mine.rms_cm:.2f}"
                f" | {peer.overshoot_cm:.1f} | {peer.settling_s:.1f} | {peer.rms_cm:.2f} |"
            )
    print()
    for name, target in TARGETS.items():
        tuned_worst = worst["tuned"][name]
        verdict = "meets" if tuned_worst <= target else "MISSES"
        print(
            f"worst {name}: tuned {tuned_worst:.2f} ({verdict} ≤ {target:g}), "
            f"default gains {worst['default'][name]:.2f}"
        )


if __name__ == "__main__":
    main()
