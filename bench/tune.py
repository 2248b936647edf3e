"""Depth-PID autotune on the simulated vehicles and several noise seeds: steps from the surface
and from mid-water with the gains of each rule, against the default gains in the same run.

Each run: the relay experiment in direct mode around 100 cm and the verification the command
runs by default (40 → 100 cm), and again with the verification from the surface (0 → 100 cm,
`--step-from 0 --min-depth 0`), for the default rule (simc) and the former one (heave-poles);
each verification's verdict with its figures from the measured depth as the command judges it
(settling time / overshoot); then 0 → 100, 20 → 100 and 40 → 100 cm depth steps, each held
15 s at its start, with the gains each rule gave and with the default gains (40, 30, 20).
Figures of these steps from the true (simulated) depth, as in bench/depth_step.py: the time
after which the depth stays within ±3 cm, and the overshoot. The simulated robot is stepped by
hand under a real client, so minutes of experiment take seconds.

    PYTHONPATH=src python bench/tune.py [--seeds 5] [--vehicles default,light,standard,heavy]
"""

from __future__ import annotations

import argparse

from rovlink.client import Client, ClientOptions
from rovlink.client.links import PortLink
from rovlink.controller.config import DepthPidConfig
from rovlink.sim.port import open_port
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
VERIFICATION = StepSettings(from_cm=40, to_cm=100)
SURFACE_VERIFICATION = StepSettings(from_cm=0, to_cm=100)
STARTS_CM = (0, 20, 40)
RULE_NAMES = ("simc", "heave-poles")


def _plant(vehicle: str, seed: int) -> tuple[Plant, Client]:
    preset = None if vehicle == "default" else vehicle
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


def tuned(
    vehicle: str, seed: int, rule: str, scales: GainScales, verification: StepSettings
) -> tuple[ProtocolGains, str]:
    """The gains the rule gives, and how its own verification went (met or missed, with the
    settling time and overshoot of the measured depth)."""
    plant, client = _plant(vehicle, seed)
    try:
        result = autotune(plant, RelaySettings(), RULES[rule], scales, verification)
    finally:
        client.close()
    assert result.step is not None
    metrics = result.step.measured
    met = all(getattr(metrics, name) <= target for name, target in TARGETS.items())
    verdict = "met" if met else "missed"
    return result.gains, f"{verdict} {metrics.settling_s:.1f} s / {metrics.overshoot_cm:.1f} cm"


def step(vehicle: str, seed: int, gains: ProtocolGains, from_cm: int) -> StepMetrics:
    plant, client = _plant(vehicle, seed)
    try:
        client.start()
        result = run_step(
            plant, gains, StepSettings(from_cm=from_cm, to_cm=100, hold_s=15.0, watch_s=40.0)
        )
        plant.stop()
    finally:
        client.close()
    assert result.true is not None
    return result.true


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--vehicles", default="default,light,standard,heavy")
    args = parser.parse_args()
    config = DepthPidConfig()
    scales = GainScales(config.kp_scale, config.ki_scale, config.kd_scale)
    reset_gains = ProtocolGains(config.kp, config.ki, config.kd)
    columns = " | ".join(f"{start} → 100 cm" for start in STARTS_CM)
    print(
        f"| vehicle | seed | gains | kp ki kd | verification 40 → 100 | from the surface | "
        f"{columns} |"
    )
    print("|---|---|---|---|---|---|" + "---|" * len(STARTS_CM))
    worst: dict[tuple[str, str, int], float] = {}
    for vehicle in args.vehicles.split(","):
        for seed in range(1, args.seeds + 1):
            sets: list[tuple[str, ProtocolGains, str]] = []
            for rule in RULE_NAMES:
                gains, verdict = tuned(vehicle, seed, rule, scales, VERIFICATION)
                _, surface = tuned(vehicle, seed, rule, scales, SURFACE_VERIFICATION)
                sets.append((rule, gains, f"{verdict} | {surface}"))
            sets.append(("default gains", reset_gains, " | "))
            for label, gains, verdict in sets:
                cells = []
                for start in STARTS_CM:
                    metrics = step(vehicle, seed, gains, start)
                    key = (vehicle, label, start)
                    worst[key] = max(worst.get(key, 0.0), metrics.settling_s)
                    cells.append(f"{metrics.settling_s:.1f} s / {metrics.overshoot_cm:.1f} cm")
                print(
                    f"| {vehicle} | {seed} | {label} | {gains.kp} {gains.ki} {gains.kd} | "
                    f"{verdict} | {' | '.join(cells)} |",
                    flush=True,
                )
    print()
    print(f"worst time to ±3 cm over the seeds | {columns}")
    for vehicle in args.vehicles.split(","):
        for label in (*RULE_NAMES, "default gains"):
            cells = " | ".join(f"{worst[vehicle, label, start]:.1f} s" for start in STARTS_CM)
            print(f"| {vehicle} | {label} | {cells} |")


if __name__ == "__main__":
    main()
