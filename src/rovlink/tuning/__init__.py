"""``rovlink tune``: depth-PID autotune by a relay experiment, a stated rule and a verification.

Example::

    from rovlink.tuning import DepthLimits, Plant, RelaySettings, RULES, autotune
    result = autotune(Plant(client, DepthLimits(20, 300)), RelaySettings(target_cm=150),
                      RULES["zn-no-overshoot"], scales, StepSettings(from_cm=50, to_cm=150))
"""

from rovlink.tuning.autotune import TuneResult, autotune
from rovlink.tuning.plant import DepthLimits, Plant, TuneAbortedError
from rovlink.tuning.relay import RelayResult, RelaySettings, run_relay
from rovlink.tuning.rules import (
    RULES,
    GainScales,
    PhysicalGains,
    ProtocolGains,
    Rule,
    physical_gains,
)
from rovlink.tuning.verify import StepResult, StepSettings, run_step

__all__ = [
    "RULES",
    "DepthLimits",
    "GainScales",
    "PhysicalGains",
    "Plant",
    "ProtocolGains",
    "RelayResult",
    "RelaySettings",
    "Rule",
    "StepResult",
    "StepSettings",
    "TuneAbortedError",
    "TuneResult",
    "autotune",
    "physical_gains",
    "run_relay",
    "run_step",
]
