"""From the relay's ultimate gain and period to PID gains, and onto the protocol's 0–99 integers.

The default rule (stated, so that anyone can redo the arithmetic) is :class:`SimcRule`: the
relay, run mid-water, gives the hull's response to thrust as a double integrator,
depth'' = b · thrust with b = (2π / Tu)² / Ku; Skogestad's SIMC rule for a double-integrating
process with the closed-loop time T = τc + θ = 0.42 s gives, in parallel form,
Kp = 1 / (2 b T²) and Kd = 1 / (b T); the integral time is Ti = 45 T (19 s), not SIMC's 8 T,
because every large depth step saturates the thrust (see :class:`SimcRule`).
:class:`HeavePolesRule` (the former default) and the Ziegler–Nichols-type rules are there to
compare: they overshoot on a hull in heave.
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
    "SimcRule",
    "ZieglerNicholsRule",
    "physical_gains",
]


@dataclass(frozen=True)
class Rule:
    """A tuning rule from the ultimate gain Ku (%/cm) and period Tu (s) to PID gains."""

    name: str
    description: str

    def gains(
        self, ultimate_gain: float, ultimate_period_s: float, max_kp: float | None = None
    ) -> PhysicalGains:
        """The PID gains the rule gives; ``max_kp`` (%/cm), the largest Kp the controller
        takes, is for rules that can slow the whole loop down to fit it (others ignore it)."""
        raise NotImplementedError


@dataclass(frozen=True)
class ZieglerNicholsRule(Rule):
    """A Ziegler–Nichols-type rule: Kp = kp · Ku, Ti = ti · Tu, Td = td · Tu."""

    kp: float = 0.6
    ti: float = 0.5
    td: float = 0.125

    def gains(
        self, ultimate_gain: float, ultimate_period_s: float, max_kp: float | None = None
    ) -> PhysicalGains:
        kp = self.kp * ultimate_gain
        return PhysicalGains(
            kp, kp / (self.ti * ultimate_period_s), kp * self.td * ultimate_period_s
        )


def _heave_response(ultimate_gain: float, ultimate_period_s: float) -> float:
    """The hull's heave as a mass pushed by thrust, from the relay: depth'' = b · thrust, with
    b = ω_u² / Ku at the oscillation's ω_u = 2π / Tu; b in cm/s² per %."""
    return (2.0 * math.pi / ultimate_period_s) ** 2 / ultimate_gain


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

    def gains(
        self, ultimate_gain: float, ultimate_period_s: float, max_kp: float | None = None
    ) -> PhysicalGains:
        plant_gain = _heave_response(ultimate_gain, ultimate_period_s)
        omega = self.bandwidth_rad_s
        kp = omega**2 / plant_gain
        ti = self.integral_periods * 2.0 * math.pi / omega
        return PhysicalGains(kp, kp / ti, 2.0 * self.damping * omega / plant_gain)


@dataclass(frozen=True)
class SimcRule(Rule):
    """Skogestad's SIMC rule for a double-integrating process, k''·e^(−θs)/s², with a long
    integral time.

    The relay, run mid-water, measures the hull away from the surface: a mass pushed by
    thrust, whose response b = (2π / Tu)² / Ku (cm/s² per %) is within 10 % of the slope of
    the thrust curve at the trim on the three simulated hulls. SIMC gives, for
    T = τc + θ (``closed_loop_s``), the cascade PID Kc = 1 / (4 b T²), τI = τD = 4 T; in the
    controller's parallel form Kp = 1 / (2 b T²) and Kd = 1 / (b T).

    SIMC's integral, Ki = Kp / (8 T), is sized for a linear loop. This one is not: a step of
    tens of cm saturates the thrust and runs at a speed the drag sets, and the controller's
    anti-windup holds the integral only while the output is saturated, so the integral
    gathers during the whole travel. With the former rule's Ti of 7.4 s (SIMC's is shorter
    still) it gathered nearly twice the trim on a 20 → 100 cm step, overshot by 6 cm and took
    12–15 s to decay. The integral's job here is the trim (the buoyancy), which a step from
    the surface must build from zero while a step in mid-water already holds it:
    ``integral_factor`` sets Ti = factor · T (19 s), long enough that what a step gathers
    stays within a few cm of either, and short enough that the trim is built within the
    settling target.

    A hull too heavy for the gain range (Kp past ``max_kp``) gets a slower loop, T stretched
    until Kp fits, rather than Kp alone held at the range's end: that left Kd and Ki sized for
    the faster loop, and the heavy hull took 13.2 and 14.4 s to settle a 20 → 100 cm step on
    two seeds of five, against 4.2 s.

    ``closed_loop_s`` and ``integral_factor`` were chosen on the simulated hulls (the default
    one and the three presets), from the surface and mid-water (docs/builders.md), for the
    reference controller's 0.5 s derivative filter and a thruster lag of about 0.1 s.
    """

    closed_loop_s: float = 0.42
    integral_factor: float = 45.0

    def gains(
        self, ultimate_gain: float, ultimate_period_s: float, max_kp: float | None = None
    ) -> PhysicalGains:
        plant_gain = _heave_response(ultimate_gain, ultimate_period_s)
        time_s = self.closed_loop_s
        if max_kp is not None and 1.0 / (2.0 * plant_gain * time_s**2) > max_kp:
            time_s = math.sqrt(1.0 / (2.0 * plant_gain * max_kp))
        kp = 1.0 / (2.0 * plant_gain * time_s**2)
        return PhysicalGains(kp, kp / (self.integral_factor * time_s), 1.0 / (plant_gain * time_s))


#: The rules ``rovlink tune --rule`` offers; the first is the default.
RULES: dict[str, Rule] = {
    rule.name: rule
    for rule in (
        SimcRule("simc", "SIMC for a double integrator, long integral time (default)"),
        HeavePolesRule("heave-poles", "mass model, poles placed; overshoots mid-water steps"),
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

    @property
    def max_kp(self) -> float:
        """The largest Kp the controller takes, %/cm: the top of ``mvpdp``'s range times
        the scale."""
        return lookup("mvpdp").arguments[0].maximum * self.kp


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


def physical_gains(
    ultimate_gain: float, ultimate_period_s: float, rule: Rule, max_kp: float | None = None
) -> PhysicalGains:
    """Apply ``rule`` to the relay experiment's Ku (%/cm) and Tu (s); ``max_kp`` is the
    largest Kp the controller takes (:meth:`GainScales.max_kp`).

    >>> physical_gains(2.0, 4.0, RULES["zn-classic"])
    PhysicalGains(kp=1.2, ki=0.6, kd=0.6)
    """
    return rule.gains(ultimate_gain, ultimate_period_s, max_kp)
