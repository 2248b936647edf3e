"""A simulated robot stepped by hand under a real client: minutes of tuning in seconds."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from rovlink.client import Client, ClientOptions
from rovlink.client.links import PortLink
from rovlink.controller.config import DepthPidConfig
from rovlink.sim.port import SimulatedPort, open_port
from rovlink.tuning import DepthLimits, GainScales, Plant

DEFAULTS = DepthPidConfig()
SCALES = GainScales(DEFAULTS.kp_scale, DEFAULTS.ki_scale, DEFAULTS.kd_scale)


@contextmanager
def simulated_plant(
    preset: str | None,
    seed: int,
    limits: DepthLimits | None = None,
    *,
    reply_timeout_s: float = 0.5,
) -> Iterator[tuple[Plant, SimulatedPort]]:
    """A plant on the preset's vehicle (None: the default vehicle, without waves) whose clock
    is the simulation's."""
    port = open_port(seed=seed, preset=preset, manual=True, timeout=0.05)
    options = ClientOptions(
        timeout_s=reply_timeout_s, keepalive_s=None, motion_timeout_s=None, boot_timeout_s=None
    )
    client = Client(PortLink(port, "sim"), options)
    clock: Callable[[], float] = lambda: port.robot.time_s  # noqa: E731
    plant = Plant(
        client,
        limits or DepthLimits(0, 400),
        clock=clock,
        sleep=port.advance,
        truth=lambda: port.vehicle.depth_m * 100.0,
    )
    try:
        yield plant, port
    finally:
        client.close()
