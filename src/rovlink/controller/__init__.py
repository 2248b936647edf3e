"""The robot's low-level controller in Python, exactly as PROTOCOL.md specifies.

:class:`Controller` is driven by received bytes and a periodic :meth:`~Controller.tick`; it reaches
the board only through the hardware-abstraction layer in :mod:`rovlink.controller.hardware`, and
is configured by :class:`ControllerConfig` (TOML through :func:`load_config`). It owns no I/O:
the simulator (:mod:`rovlink.sim`) or a real board's main loop owns the clock and the serial line.
"""

from rovlink.controller.config import (
    DEFAULT_THRUSTERS,
    ConfigError,
    ControllerConfig,
    DepthCalibration,
    DepthPidConfig,
    LeakAction,
    ThrusterSpec,
    config_from_mapping,
    config_reference,
    load_config,
)
from rovlink.controller.controller import Controller, ControllerState
from rovlink.controller.hardware import (
    Attitude,
    ClawMotor,
    Clock,
    Hardware,
    Imu,
    LeakSensor,
    PressureSensor,
    ThrusterOutputs,
)
from rovlink.controller.mixer import ThrusterMixer
from rovlink.controller.pid import DepthPid

__all__ = [
    "DEFAULT_THRUSTERS",
    "Attitude",
    "ClawMotor",
    "Clock",
    "ConfigError",
    "Controller",
    "ControllerConfig",
    "ControllerState",
    "DepthCalibration",
    "DepthPid",
    "DepthPidConfig",
    "Hardware",
    "Imu",
    "LeakAction",
    "LeakSensor",
    "PressureSensor",
    "ThrusterMixer",
    "ThrusterOutputs",
    "ThrusterSpec",
    "config_from_mapping",
    "config_reference",
    "load_config",
]
