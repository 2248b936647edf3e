"""The simulated robot: vehicle physics, simulated devices, and the controller running on them.

* :class:`SimulatedRobot` — controller + physics, stepped in simulated time (deterministic).
* :func:`open_port` — an in-process, pyserial-like port to a simulated controller.
* :mod:`rovlink.sim.server` — the controller on a pseudo-terminal and/or TCP (``rovlink sim``).
"""

from rovlink.sim.devices import SensorParams
from rovlink.sim.port import SimulatedPort, open_port
from rovlink.sim.robot import SimConfig, SimulatedRobot, load_sim_config
from rovlink.sim.vehicle import Vehicle, VehicleParams

__all__ = [
    "SensorParams",
    "SimConfig",
    "SimulatedPort",
    "SimulatedRobot",
    "Vehicle",
    "VehicleParams",
    "load_sim_config",
    "open_port",
]
