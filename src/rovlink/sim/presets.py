"""Simulated vehicles that differ in mass, buoyancy and drag, with heave waves on.

For tuning depth control against more than one hull (``rovlink tune``) and for anyone who wants a
light or a heavy robot without writing a ``[vehicle]`` table: ``sim://?preset=heavy``,
``rovlink sim --preset light``.

>>> sorted(PRESETS)
['heavy', 'light', 'standard']
>>> PRESETS["heavy"].mass_kg
30.0
"""

from __future__ import annotations

import dataclasses

from rovlink.sim.robot import SimConfig
from rovlink.sim.vehicle import VehicleParams

__all__ = ["PRESETS", "preset_config"]

_STANDARD = VehicleParams()

#: Each preset's vehicle. Thrusters are the default ones (2 × 2.5 kgf vertical) on every hull.
PRESETS: dict[str, VehicleParams] = {
    # A small, quick hull: little mass and drag, slightly buoyant; waves move it most.
    "light": dataclasses.replace(
        _STANDARD,
        mass_kg=6.0,
        added_mass_heave_kg=3.0,
        net_buoyancy_n=1.0,
        heave_drag_n_s2_m2=25.0,
        heave_linear_drag_n_s_m=1.0,
        wave_heave_n=0.5,
    ),
    # The default vehicle, with heave waves.
    "standard": dataclasses.replace(_STANDARD, wave_heave_n=0.75),
    # A heavy work-class hull: five times the mass of the light one, more buoyant, more drag.
    "heavy": dataclasses.replace(
        _STANDARD,
        mass_kg=30.0,
        added_mass_heave_kg=20.0,
        net_buoyancy_n=4.0,
        heave_drag_n_s2_m2=120.0,
        heave_linear_drag_n_s_m=4.0,
        wave_heave_n=1.5,
    ),
}


def preset_config(name: str, base: SimConfig | None = None) -> SimConfig:
    """``base`` (default: the default configuration) with the preset's vehicle.

    >>> preset_config("light").vehicle.mass_kg
    6.0
    """
    try:
        vehicle = PRESETS[name]
    except KeyError:
        known = ", ".join(sorted(PRESETS))
        raise ValueError(f"unknown vehicle preset {name!r}; known: {known}") from None
    return dataclasses.replace(base or SimConfig(), vehicle=vehicle)
