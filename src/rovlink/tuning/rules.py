"""From the ultimate gain and period to PID gains, and onto the protocol's 0–99 integers.

The default rule (stated, so that anyone can redo the arithmetic) is :class:`HeavePolesRule`:
the relay's Ku and Tu give the hull's response to thrust, b = (2π / Tu)² / Ku, and the gains
place the closed loop's poles: Kp = ω² / b, Kd = 2 ζ ω / b, Ki = Kp / Ti with Ti = 2 · 2π / ω,
for ω = 1.7 rad/s and ζ = 1.0. The Ziegler–Nichols-type rules are there to compare: they assume
a lag-dominated process, which a hull in heave is not, and overshoot on it.
The controller's PID works in % thrust per cm (P10): the integers are the physical gains divided
by the controller's scales (``[depth_pid]`` ``kp_scale``, ``ki_scale``, ``kd_scale``), rounded
and held within 0–99.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rovlink.protocol import lookup

__all__ = [
    "RULES",
    "GainScales",
    "HeavePolesRule",
    "PhysicalGains",
    "ProtocolGains",
    "Rule",
    "ZieglerNicholsRule",
    "physical_gains",
]


@dataclass(frozen=True)
class Rule:
    """A tuning rule from the ultimate gain Ku (%/cm) and period Tu (s) to PID gains."""

    name: str
    description: str

    def gains(self, ultimate_gain: float, ultimate_period_s: float) -> PhysicalGains:
        """The PID gains the rule gives."""
        raise NotImplementedError


@dataclass(frozen=True)
class ZieglerNicholsRule(Rule):
    """A Ziegler–Nichols-type rule: Kp = kp · Ku, Ti = ti · Tu, Td = td · Tu."""

    kp: float = 0.6
    ti: float = 0.5
    td: float = 0.125

    def gains(self, ultimate_gain: float, ultimate_period_s: float) -> PhysicalGains:
        kp = self.kp * ultimate_gain
        return PhysicalGains(
            kp, kp / (self.ti * ultimate_period_s), kp * self.td * ultimate_period_s
        )


@dataclass(frozen=True)
class HeavePolesRule(Rule):
    """The heave of a hull is close to a mass pushed by thrust: depth'' = b · thrust. At the
    relay's oscillation that mass answers with gain Ku at ω_u = 2π / Tu, so b = ω_u² / Ku.
    The gains then place the closed loop's poles at ``bandwidth_rad_s`` with damping
    ``damping``: Kp = ω² / b, Kd = 2 ζ ω / b, and the integral (for the trim) acts over
    ``integral_periods`` periods of the closed loop: Ti = integral_periods · 2π / ω."""

    bandwidth_rad_s: float = 1.7
    damping: float = 1.0
    integral_periods: float = 2.0

    def gains(self, ultimate_gain: float, ultimate_period_s: float) -> PhysicalGains:
        plant_gain = (2.0 * math.pi / ultimate_period_s) ** 2 / ultimate_gain  # cm/s² per %
        omega = self.bandwidth_rad_s
        kp = omega**2 / plant_gain
        ti = self.integral_periods * 2.0 * math.pi / omega
        return PhysicalGains(kp, kp / ti, 2.0 * self.damping * omega / plant_gain)


#: The rules ``rovlink tune --rule`` offers; the first is the default.
RULES: dict[str, Rule] = {
    rule.name: rule
    for rule in (
        HeavePolesRule("heave-poles", "mass model from the relay, poles placed (default)"),
        ZieglerNicholsRule("zn-no-overshoot", "Ziegler–Nichols, no overshoot", 0.2, 0.5, 1 / 3),
        ZieglerNicholsRule("zn-classic", "Ziegler–Nichols, classic", 0.6, 0.5, 0.125),
        ZieglerNicholsRule("tyreus-luyben", "Tyreus–Luyben", 0.45, 2.2, 1 / 6.3),
    )
}


@dataclass(frozen=True)
class GainScales:
    """The controller's scales: % thrust per unit of each integer gain (``[depth_pid]``)."""

    kp: float
    ki: float
    kd: float


@dataclass(frozen=True)
class PhysicalGains:
    """PID gains in the controller's units: %/cm, %/(cm·s), %/(cm/s)."""

    kp: float
    ki: float
    kd: float

    def to_protocol(self, scales: GainScales) -> ProtocolGains:
        """The integers for ``mvpdp``, ``mvpdi``, ``mvpidd``, within the table's range."""
        gain = lookup("mvpdp").arguments[0]
        wanted = (self.kp / scales.kp, self.ki / scales.ki, self.kd / scales.kd)
        clipped = tuple(max(gain.minimum, min(gain.maximum, round(value))) for value in wanted)
        saturated = tuple(
            name
            for name, value, result in zip(("kp", "ki", "kd"), wanted, clipped, strict=True)
            if round(value) != result
        )
        return ProtocolGains(clipped[0], clipped[1], clipped[2], saturated)


@dataclass(frozen=True)
class ProtocolGains:
    """The gains as the protocol sends them, and which of them hit the 0–99 range."""

    kp: int
    ki: int
    kd: int
    saturated: tuple[str, ...] = ()


def physical_gains(ultimate_gain: float, ultimate_period_s: float, rule: Rule) -> PhysicalGains:
    """Apply ``rule`` to the relay experiment's Ku (%/cm) and Tu (s).

    >>> physical_gains(2.0, 4.0, RULES["zn-classic"])
    PhysicalGains(kp=1.2, ki=0.6, kd=0.6)
    """
    return rule.gains(ultimate_gain, ultimate_period_s)
